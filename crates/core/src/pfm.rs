//! Portable float maps (PFM): the plain HDR format of the Mitsuba
//! references (`src/mitsuba/reference.rs`) and of users' environment maps
//! ([`crate::sky::envmap`]). `PF` is RGB, `Pf` grey (read as RGB); a
//! negative scale means little-endian; rows are stored bottom first and
//! returned top first. Writing lives with the images that are written
//! (`crates/runtime/src/tonemap.rs`).

/// A decoded map: `width × height` RGB texels, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Pfm {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<[f32; 3]>,
}

/// The largest side accepted: 65,536 texels.
pub const MAX_SIDE: usize = 65_536;

/// Decodes `bytes`; `max_texels` bounds the allocation (checked before
/// it). The error says what is wrong (the caller names the file).
/// Non-finite texels are an error: neither a reference nor a sky may hold
/// one.
pub fn decode(bytes: &[u8], max_texels: usize) -> Result<Pfm, String> {
    // The magic and three whitespace-separated fields (width, height,
    // scale), then one whitespace byte.
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && !bytes[i].is_ascii_whitespace() && i - start < 64 {
            i += 1;
        }
        if start == i {
            return Err("truncated header".into());
        }
        fields.push(String::from_utf8_lossy(&bytes[start..i]).into_owned());
    }
    i += 1;
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        other => return Err(format!("magic {other:?}, expected \"PF\" or \"Pf\"")),
    };
    let parse = |s: &str| {
        s.parse::<usize>()
            .ok()
            .filter(|&v| (1..=MAX_SIDE).contains(&v))
    };
    let (Some(w), Some(h)) = (parse(&fields[1]), parse(&fields[2])) else {
        return Err(format!(
            "size {} x {} (each side 1 to {MAX_SIDE})",
            fields[1], fields[2]
        ));
    };
    if w * h > max_texels {
        return Err(format!(
            "{w} x {h} texels, more than the {max_texels} accepted"
        ));
    }
    let scale: f32 = fields[3]
        .parse()
        .ok()
        .filter(|s: &f32| s.is_finite() && *s != 0.0)
        .ok_or_else(|| format!("scale {:?}", fields[3]))?;
    let little = scale < 0.0;
    let need = w * h * 4 * channels;
    let data = bytes.get(i..i + need).ok_or_else(|| {
        format!(
            "{} bytes of pixels, {w} x {h} needs {need}",
            bytes.len().saturating_sub(i)
        )
    })?;
    let mut texels = vec![[0.0f32; 3]; w * h];
    for (k, chunk) in data.chunks_exact(4).enumerate() {
        let b = [chunk[0], chunk[1], chunk[2], chunk[3]];
        let v = if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        };
        let (p, c) = (k / channels, k % channels);
        let (x, y_bottom) = (p % w, p / w);
        if !v.is_finite() {
            return Err(format!(
                "a non-finite value {v} at pixel ({x}, {}) (top row 0)",
                h - 1 - y_bottom
            ));
        }
        let t = &mut texels[(h - 1 - y_bottom) * w + x];
        if channels == 1 {
            *t = [v; 3];
        } else {
            t[c] = v;
        }
    }
    Ok(Pfm {
        width: w,
        height: h,
        texels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(magic: &str, w: usize, h: usize, scale: f32, values: &[f32]) -> Vec<u8> {
        let mut out = format!("{magic}\n{w} {h}\n{scale}\n").into_bytes();
        for v in values {
            if scale < 0.0 {
                out.extend_from_slice(&v.to_le_bytes());
            } else {
                out.extend_from_slice(&v.to_be_bytes());
            }
        }
        out
    }

    /// Rows come back top first, either byte order, grey as RGB.
    #[test]
    fn rows_flip_and_both_byte_orders_read() {
        // Bottom row (1, 2, 3), top row (4, 5, 6): a 1 x 2 colour map.
        let v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        for scale in [-1.0, 1.0] {
            let p = decode(&file("PF", 1, 2, scale, &v), 100).unwrap();
            assert_eq!(p.texels, vec![[4.0, 5.0, 6.0], [1.0, 2.0, 3.0]]);
        }
        let p = decode(&file("Pf", 2, 1, -1.0, &[7.0, 8.0]), 100).unwrap();
        assert_eq!(p.texels, vec![[7.0; 3], [8.0; 3]]);
    }

    #[test]
    fn bad_maps_say_what_is_wrong() {
        let e = decode(&file("P6", 1, 1, -1.0, &[0.0; 3]), 100).unwrap_err();
        assert!(e.contains("magic"), "{e}");
        let e = decode(&file("PF", 2, 2, -1.0, &[0.0; 3]), 100).unwrap_err();
        assert!(e.contains("needs 48"), "{e}");
        let e = decode(&file("PF", 100, 100, -1.0, &[]), 100).unwrap_err();
        assert!(e.contains("more than"), "{e}");
        let e = decode(&file("PF", 1, 1, -1.0, &[0.0, f32::NAN, 0.0]), 100).unwrap_err();
        assert!(e.contains("non-finite"), "{e}");
        assert!(decode(b"PF\n1", 100).is_err());
    }
}

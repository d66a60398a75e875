//! A minimal NumPy `.npy` writer and reader for little-endian `f32` arrays in
//! C (row-major) order, format version 1.0.
//!
//! The format (NumPy's `numpy/lib/format.py`, "NEP 1 — A simple file format
//! for NumPy arrays"): the magic string `\x93NUMPY`, the version bytes
//! `1 0`, a little-endian `u16` header length, then an ASCII Python dict
//! literal `{'descr': '<f4', 'fortran_order': False, 'shape': (a, b), }`
//! padded with spaces and ended by `\n` so that the data starts at a
//! multiple of 64 bytes (NumPy ≥ 1.x pads to 64; readers accept any
//! padding), then the raw data. `numpy.load` reads what [`write_f32`]
//! writes, and [`read_f32`] reads what `numpy.save` writes for a C-order
//! `float32` array.
//!
//! Only what the project needs is supported; anything else (another dtype,
//! Fortran order, a version-2 header, a truncated file) is a clear error,
//! never a guess.

use std::io::{Read, Write};
use std::path::Path;

/// The magic bytes that open every `.npy` file.
pub const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// Errors of this module, each naming the file and what was wrong.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a NumPy .npy v1.0 float32 C-order file: {message}")]
    Format { path: String, message: String },
    #[error("shape {shape:?} holds {expected} values but {got} were given")]
    Shape {
        shape: Vec<usize>,
        expected: usize,
        got: usize,
    },
}

/// The header dict for a C-order little-endian f32 array of `shape`, padded
/// so that magic + version + length + header is a multiple of 64 bytes.
fn header(shape: &[usize]) -> Vec<u8> {
    let dims = match shape {
        [one] => format!("({one},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {dims}, }}");
    // 6 magic + 2 version + 2 length bytes precede the dict; the dict ends
    // with '\n'.
    let unpadded = 10 + dict.len() + 1;
    let pad = unpadded.next_multiple_of(64) - unpadded;
    dict.extend(std::iter::repeat_n(' ', pad));
    dict.push('\n');
    dict.into_bytes()
}

/// Writes `data` (C order, `shape.iter().product()` values) as a `.npy`
/// v1.0 file of dtype `<f4`.
pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), NpyError> {
    let expected: usize = shape.iter().product();
    if expected != data.len() {
        return Err(NpyError::Shape {
            shape: shape.to_vec(),
            expected,
            got: data.len(),
        });
    }
    let io = |source| NpyError::Io {
        path: path.display().to_string(),
        source,
    };
    let head = header(shape);
    let len = u16::try_from(head.len()).map_err(|_| NpyError::Format {
        path: path.display().to_string(),
        message: format!(
            "a shape of {} dimensions does not fit a v1.0 header",
            shape.len()
        ),
    })?;
    let file = std::fs::File::create(path).map_err(io)?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    w.write_all(MAGIC).map_err(io)?;
    w.write_all(&[1, 0]).map_err(io)?;
    w.write_all(&len.to_le_bytes()).map_err(io)?;
    w.write_all(&head).map_err(io)?;
    // Little-endian bytes, in chunks so that memory stays bounded.
    let mut buf = Vec::with_capacity(1 << 20);
    for chunk in data.chunks(1 << 18) {
        buf.clear();
        for v in chunk {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        w.write_all(&buf).map_err(io)?;
    }
    w.flush().map_err(io)?;
    Ok(())
}

/// Reads a `.npy` v1.0 file of dtype `<f4` in C order; returns the shape
/// and the values.
pub fn read_f32(path: &Path) -> Result<(Vec<usize>, Vec<f32>), NpyError> {
    let name = path.display().to_string();
    let io = |source| NpyError::Io {
        path: name.clone(),
        source,
    };
    let bad = |message: String| NpyError::Format {
        path: name.clone(),
        message,
    };
    let mut file = std::io::BufReader::new(std::fs::File::open(path).map_err(io)?);
    let mut pre = [0u8; 10];
    file.read_exact(&mut pre)
        .map_err(|e| bad(format!("cannot read the 10-byte preamble ({e})")))?;
    if &pre[..6] != MAGIC {
        return Err(bad("the magic string \\x93NUMPY is missing".into()));
    }
    if pre[6..8] != [1, 0] {
        return Err(bad(format!(
            "format version {}.{} (only 1.0 is supported)",
            pre[6], pre[7]
        )));
    }
    let hlen = u16::from_le_bytes([pre[8], pre[9]]) as usize;
    let mut head = vec![0u8; hlen];
    file.read_exact(&mut head)
        .map_err(|e| bad(format!("truncated header of {hlen} bytes ({e})")))?;
    let head = String::from_utf8(head).map_err(|_| bad("the header is not ASCII".into()))?;
    let field = |key: &str| -> Result<String, NpyError> {
        let at = head
            .find(&format!("'{key}'"))
            .ok_or_else(|| bad(format!("the header has no '{key}': {head:?}")))?;
        let rest = &head[at + key.len() + 2..];
        let rest = rest
            .trim_start()
            .strip_prefix(':')
            .ok_or_else(|| bad(format!("malformed '{key}' in {head:?}")))?
            .trim_start();
        // A tuple value runs to its ')'; a scalar to the next ','.
        let end = if rest.starts_with('(') {
            rest.find(')').map(|e| e + 1)
        } else {
            rest.find([',', '}'])
        }
        .ok_or_else(|| bad(format!("malformed '{key}' in {head:?}")))?;
        Ok(rest[..end].trim().to_string())
    };
    let descr = field("descr")?;
    if descr != "'<f4'" {
        return Err(bad(format!("dtype {descr} (only '<f4' is supported)")));
    }
    let fortran = field("fortran_order")?;
    if fortran != "False" {
        return Err(bad(format!(
            "fortran_order {fortran} (only C order is supported)"
        )));
    }
    let shape_text = field("shape")?;
    let inner = shape_text
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| bad(format!("malformed shape {shape_text}")))?;
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| bad(format!("malformed shape {shape_text}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let count = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| bad(format!("shape {shape_text} overflows")))?;
    let bytes = count
        .checked_mul(4)
        .ok_or_else(|| bad(format!("shape {shape_text} overflows")))?;
    let mut raw = vec![0u8; bytes];
    file.read_exact(&mut raw).map_err(|e| {
        bad(format!(
            "truncated data: shape {shape_text} needs {bytes} bytes ({e})"
        ))
    })?;
    let mut extra = [0u8; 1];
    if file.read(&mut extra).map_err(io)? != 0 {
        return Err(bad(format!(
            "data continues past the {bytes} bytes of shape {shape_text}"
        )));
    }
    let data = raw
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((shape, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_aligned_and_parses_back() {
        for shape in [vec![3usize], vec![2, 5], vec![0, 0], vec![12345, 678, 9]] {
            let h = header(&shape);
            assert_eq!((10 + h.len()) % 64, 0);
            assert!(h.ends_with(b"\n"));
        }
        let dir = std::env::temp_dir().join(format!("radiosity-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.npy");
        let data: Vec<f32> = (0..15).map(|i| i as f32 * 0.25 - 1.0).collect();
        write_f32(&p, &[3, 5], &data).unwrap();
        let (shape, back) = read_f32(&p).unwrap();
        assert_eq!(shape, vec![3, 5]);
        assert_eq!(back, data);
        write_f32(&p, &[15], &data).unwrap();
        assert_eq!(read_f32(&p).unwrap().0, vec![15]);
        assert!(write_f32(&p, &[4, 4], &data).is_err());
        // A truncated file is an error, not a short array.
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 1]).unwrap();
        assert!(matches!(read_f32(&p), Err(NpyError::Format { .. })));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

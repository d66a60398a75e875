//! Reading Mitsuba's reference images back (`scripts/mitsuba-reference`
//! writes them) and measuring an image against them.
//!
//! Each reference view comes as two independent halves `a` and `b` (the
//! same samples per pixel, different seeds), so the reference's noise is
//! known per pixel: with `m = (a + b) / 2`, `E[((a − b)/2)²] = Var(m)`.
//! The error of an image `o` is the relative RMS over pixels and channels,
//! `sqrt(Σ (o − r)² / Σ r²)` against the noise-free reference `r`; since
//! `E[(o − m)²] = (o − r)² + Var(m)`, subtracting `Σ ((a − b)/2)²` from
//! `Σ (o − m)²` removes the reference's noise without bias
//! ([`ImageError::rel_rms`]). The raw figure and the noise itself are kept
//! beside it, so a reader can see how much was removed.
//!
//! The views match the run time's ([`crate::runtime::render::View`]):
//! direct `= le + lights`, final `= final`, indirect `= final − direct`
//! (module doc of [`mod@super::export`]).

use std::path::{Path, PathBuf};

/// An error reading a reference.
#[derive(Debug, thiserror::Error)]
pub enum ReferenceError {
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A PFM file is malformed.
    #[error("{path}: not a colour PFM ({what})")]
    Pfm { path: PathBuf, what: String },
    /// The images of one reference differ in size.
    #[error("{path}: {width} x {height}, expected {expected_width} x {expected_height}")]
    Size {
        path: PathBuf,
        width: usize,
        height: usize,
        expected_width: usize,
        expected_height: usize,
    },
    /// `meta.json` is missing a field or unreadable.
    #[error("{path}: {what}")]
    Meta { path: PathBuf, what: String },
}

/// A linear RGB image, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

/// Reads a PFM ([`crate::core::pfm`]) into an image with the top row
/// first. Non-finite pixels are an error: a reference must be finite
/// everywhere.
pub fn read_pfm(path: &Path) -> Result<Rgb, ReferenceError> {
    let bytes = std::fs::read(path).map_err(|source| ReferenceError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let p = crate::core::pfm::decode(&bytes, usize::MAX).map_err(|what| ReferenceError::Pfm {
        path: path.to_path_buf(),
        what,
    })?;
    Ok(Rgb {
        width: p.width,
        height: p.height,
        pixels: p.texels,
    })
}

/// The reference's images, each view as its two halves.
#[derive(Clone, Debug)]
pub struct Reference {
    pub width: usize,
    pub height: usize,
    /// Samples per pixel, both halves together.
    pub spp: u32,
    /// `"inf"` or the number of bounces of the final image.
    pub bounces: String,
    pub direct: [Vec<[f32; 3]>; 2],
    /// `None` when only the direct view was rendered.
    pub final_: Option<[Vec<[f32; 3]>; 2]>,
    pub indirect: Option<[Vec<[f32; 3]>; 2]>,
}

impl Reference {
    /// Reads the reference in `dir` (what `scripts/mitsuba-reference -o
    /// DIR` wrote).
    pub fn load(dir: &Path) -> Result<Reference, ReferenceError> {
        let meta_path = dir.join("meta.json");
        let text = std::fs::read_to_string(&meta_path).map_err(|source| ReferenceError::Io {
            path: meta_path.clone(),
            source,
        })?;
        let meta: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| ReferenceError::Meta {
                path: meta_path.clone(),
                what: e.to_string(),
            })?;
        let field = |k: &str| {
            meta.get(k).cloned().ok_or_else(|| ReferenceError::Meta {
                path: meta_path.clone(),
                what: format!("no field `{k}`"),
            })
        };
        let spp = field("spp")?.as_u64().unwrap_or(0) as u32;
        let bounces = match field("bounces")? {
            serde_json::Value::String(s) => s,
            v => v.to_string(),
        };
        let views = field("views")?.as_str().unwrap_or("all").to_string();
        let mut size = None;
        let mut read = |name: &str| -> Result<[Vec<[f32; 3]>; 2], ReferenceError> {
            let mut halves = [Vec::new(), Vec::new()];
            for (k, tag) in ["a", "b"].iter().enumerate() {
                let path = dir.join(format!("{name}_{tag}.pfm"));
                let img = read_pfm(&path)?;
                let (ew, eh) = *size.get_or_insert((img.width, img.height));
                if (img.width, img.height) != (ew, eh) {
                    return Err(ReferenceError::Size {
                        path,
                        width: img.width,
                        height: img.height,
                        expected_width: ew,
                        expected_height: eh,
                    });
                }
                halves[k] = img.pixels;
            }
            Ok(halves)
        };
        let le = read("le")?;
        let lights = read("lights")?;
        let direct = [0, 1].map(|k| add(&le[k], &lights[k], 1.0));
        let (final_, indirect) = if views == "all" {
            let f = read("final")?;
            let ind = [0, 1].map(|k| add(&f[k], &direct[k], -1.0));
            (Some(f), Some(ind))
        } else {
            (None, None)
        };
        let (width, height) = size.unwrap_or((0, 0));
        Ok(Reference {
            width,
            height,
            spp,
            bounces,
            direct,
            final_,
            indirect,
        })
    }
}

fn add(a: &[[f32; 3]], b: &[[f32; 3]], s: f32) -> Vec<[f32; 3]> {
    a.iter()
        .zip(b)
        .map(|(x, y)| std::array::from_fn(|c| x[c] + s * y[c]))
        .collect()
}

/// An image's error against a reference view (module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ImageError {
    /// Relative RMS error against the noise-free reference (the
    /// reference's noise removed; 0 when the noise explains it all).
    pub rel_rms: f64,
    /// Relative RMS difference from the reference's mean, noise included.
    pub raw_rel_rms: f64,
    /// The reference's own noise: relative RMS of its mean's per-pixel
    /// standard error.
    pub noise: f64,
    /// Relative mean difference `Σ (o − r) / Σ r` (over channels): the
    /// overall bias, too dark when negative.
    pub bias: f64,
}

/// The error of `ours` (top row first, the reference's size) against the
/// two halves of a reference view.
pub fn image_error(ours: &[[f32; 3]], halves: &[Vec<[f32; 3]>; 2]) -> ImageError {
    let (mut d2, mut n2, mut r2, mut d, mut r) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for ((o, a), b) in ours.iter().zip(&halves[0]).zip(&halves[1]) {
        for c in 0..3 {
            let m = 0.5 * (a[c] as f64 + b[c] as f64);
            let half_diff = 0.5 * (a[c] as f64 - b[c] as f64);
            let e = o[c] as f64 - m;
            d2 += e * e;
            n2 += half_diff * half_diff;
            r2 += m * m;
            d += e;
            r += m;
        }
    }
    if !(r2 > 0.0) {
        // A black reference: exact only if ours is black too.
        let e = if d2 > 0.0 { f64::INFINITY } else { 0.0 };
        return ImageError {
            rel_rms: e,
            raw_rel_rms: e,
            noise: 0.0,
            bias: e,
        };
    }
    ImageError {
        rel_rms: ((d2 - n2).max(0.0) / r2).sqrt(),
        raw_rel_rms: (d2 / r2).sqrt(),
        noise: (n2 / r2).sqrt(),
        bias: if r > 0.0 { d / r } else { 0.0 },
    }
}

/// Box-downsamples `pixels` (`width × height`, top row first) by `s` in
/// each direction: the mean of each `s × s` block, as Mitsuba's box filter
/// averages over each pixel's area. `width` and `height` must be multiples
/// of `s`.
pub fn downsample(pixels: &[[f32; 3]], width: usize, height: usize, s: usize) -> Vec<[f32; 3]> {
    let (w, h) = (width / s, height / s);
    let mut out = vec![[0.0f32; 3]; w * h];
    let inv = 1.0 / (s * s) as f32;
    for y in 0..h * s {
        for x in 0..w * s {
            let p = pixels[y * width + x];
            let q = &mut out[(y / s) * w + x / s];
            for c in 0..3 {
                q[c] += p[c] * inv;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_round_trip_keeps_rows_in_order() {
        let dir = std::env::temp_dir().join(format!("pfm-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("x.pfm");
        let px: Vec<[f32; 3]> = (0..6).map(|i| [i as f32, 2.0 * i as f32, -1.0]).collect();
        crate::runtime::tonemap::write_pfm(&path, 3, 2, &px).unwrap();
        let img = read_pfm(&path).unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.pixels, px);
        std::fs::write(&path, b"PF\n3 2\n-1.0\n\0\0").unwrap();
        assert!(read_pfm(&path)
            .unwrap_err()
            .to_string()
            .contains("needs 72"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn noise_is_removed_without_bias() {
        // A constant reference 1 with independent ±0.3 noise per half: the
        // raw error of a perfect image is the noise (0.3/√2 ≈ 0.21), the
        // corrected one near 0; an image 10 % too bright shows 10 %.
        let mut rng = crate::core::math::SplitMix64::new(7);
        let n = 20_000;
        let mut half = || -> Vec<[f32; 3]> {
            (0..n)
                .map(|_| [0; 3].map(|_| 1.0 + 0.3 * (2.0 * rng_f(&mut rng) - 1.0) * 3f32.sqrt()))
                .collect()
        };
        fn rng_f(r: &mut crate::core::math::SplitMix64) -> f32 {
            r.uniform() as f32
        }
        let halves = [half(), half()];
        let exact = vec![[1.0f32; 3]; n];
        let e = image_error(&exact, &halves);
        assert!((e.noise - 0.3 / 2f64.sqrt()).abs() < 0.01, "{e:?}");
        assert!(e.rel_rms < 0.02, "{e:?}");
        let black = [vec![[0.0f32; 3]; 4], vec![[0.0f32; 3]; 4]];
        assert_eq!(image_error(&[[0.0; 3]; 4], &black).rel_rms, 0.0);
        assert!(image_error(&[[0.1; 3]; 4], &black).rel_rms.is_infinite());
        let bright = vec![[1.1f32; 3]; n];
        let e = image_error(&bright, &halves);
        assert!((e.rel_rms - 0.1).abs() < 0.01, "{e:?}");
        assert!((e.bias - 0.1).abs() < 0.01, "{e:?}");
    }

    #[test]
    fn downsample_averages_blocks() {
        let px: Vec<[f32; 3]> = (0..16).map(|i| [i as f32; 3]).collect();
        let d = downsample(&px, 4, 4, 2);
        assert_eq!(d, vec![[2.5; 3], [4.5; 3], [10.5; 3], [12.5; 3]]);
    }
}

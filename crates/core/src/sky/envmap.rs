//! Environment maps: a latitude-longitude image of the sky's radiance
//! (`.hdr`, `.exr` or `.pfm`), in Mitsuba 3's convention so that one file
//! means the same sky to both renderers: the direction `d` (`+y` up) is
//! at `u = atan2(d_x, −d_z) / 2π` (wrapped to [0, 1)) across and
//! `v = acos(d_y) / π` down, the top row the zenith. Texel values are
//! radiance in W/(m² sr) before the sky's `intensity`.
//!
//! The map is read once, when the camera-and-lights file is ([`load`]),
//! and shared by the clones of its sky ([`Shared`]).

use crate::error::ImageError;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The most texels a map may have (16k × 8k, 1.5 GiB as f32 RGB): checked
/// before the texels are allocated for PFM, and by the decoder's own
/// allocation limit for the others.
pub const MAX_TEXELS: usize = 16_384 * 8_192;

/// A latitude-longitude map, top row first (module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct LatLong {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<[f32; 3]>,
    /// The file it was read from.
    pub path: PathBuf,
    /// The largest texel value, any channel (the sky's bound checks it).
    pub brightest: f32,
}

/// Why a map could not be read.
#[derive(Debug, thiserror::Error)]
pub enum EnvMapError {
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error("{path}: not a PFM map ({what})")]
    Pfm { path: PathBuf, what: String },
    #[error("{path}: unknown extension (an environment map is .hdr, .exr or .pfm)")]
    Extension { path: PathBuf },
    #[error(
        "{path}: radiance {value} at pixel ({x}, {y}): a sky's radiance must be finite and ≥ 0"
    )]
    Value {
        path: PathBuf,
        x: usize,
        y: usize,
        value: f32,
    },
}

/// Reads the map at `path` (the format from its extension).
pub fn load(path: &Path) -> Result<LatLong, EnvMapError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let read = |p: &Path| {
        std::fs::read(p).map_err(|source| ImageError::Read {
            path: p.to_path_buf(),
            source,
        })
    };
    let (width, height, texels) = match ext.as_deref() {
        Some("pfm") => {
            let p =
                crate::pfm::decode(&read(path)?, MAX_TEXELS).map_err(|what| EnvMapError::Pfm {
                    path: path.to_path_buf(),
                    what,
                })?;
            (p.width, p.height, p.texels)
        }
        Some("hdr" | "exr") => {
            let what = path.display().to_string();
            let decode = |source| ImageError::Decode {
                what: what.clone(),
                source,
            };
            let mut reader = image::ImageReader::new(std::io::Cursor::new(read(path)?))
                .with_guessed_format()
                .map_err(|source| ImageError::Read {
                    path: path.to_path_buf(),
                    source,
                })?;
            let mut limits = image::Limits::default();
            limits.max_alloc = Some(16 * MAX_TEXELS as u64);
            reader.limits(limits);
            let img = reader.decode().map_err(decode)?.into_rgb32f();
            let (w, h) = (img.width() as usize, img.height() as usize);
            if w == 0 || h == 0 {
                return Err(ImageError::Empty { what }.into());
            }
            let texels = img.pixels().map(|p| p.0).collect();
            (w, h, texels)
        }
        _ => {
            return Err(EnvMapError::Extension {
                path: path.to_path_buf(),
            })
        }
    };
    if let Some((k, t)) = texels
        .iter()
        .enumerate()
        .find(|(_, t)| !t.iter().all(|v| v.is_finite() && *v >= 0.0))
    {
        let value = *t
            .iter()
            .find(|v| !(v.is_finite() && **v >= 0.0))
            .unwrap_or(&t[0]);
        return Err(EnvMapError::Value {
            path: path.to_path_buf(),
            x: k % width,
            y: k / width,
            value,
        });
    }
    let brightest = texels.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
    Ok(LatLong {
        width,
        height,
        texels,
        path: path.to_path_buf(),
        brightest,
    })
}

/// The direction at map coordinates `(u, v)` ∈ [0, 1]² (module doc).
pub fn direction(u: f64, v: f64) -> [f64; 3] {
    let (phi, theta) = (2.0 * std::f64::consts::PI * u, std::f64::consts::PI * v);
    [
        phi.sin() * theta.sin(),
        theta.cos(),
        -phi.cos() * theta.sin(),
    ]
}

/// The map coordinates of the unit direction `d` (module doc).
pub fn coordinates(d: [f64; 3]) -> (f64, f64) {
    let u = d[0].atan2(-d[2]) / (2.0 * std::f64::consts::PI);
    (
        u - u.floor(),
        d[1].clamp(-1.0, 1.0).acos() / std::f64::consts::PI,
    )
}

impl LatLong {
    /// The radiance towards `d`: bilinear between texel centres, wrapping
    /// across `u` and clamped at the poles.
    pub fn lookup(&self, d: [f64; 3]) -> [f64; 3] {
        let (u, v) = coordinates(d);
        let (w, h) = (self.width, self.height);
        let x = u * w as f64 - 0.5;
        let y = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let xi = |k: f64| (k as i64).rem_euclid(w as i64) as usize;
        let (xa, xb) = (xi(x0), xi(x0 + 1.0));
        let (ya, yb) = (y0 as usize, (y0 as usize + 1).min(h - 1));
        let t = |x: usize, y: usize| self.texels[y * w + x].map(f64::from);
        let (a, b, c, e) = (t(xa, ya), t(xb, ya), t(xa, yb), t(xb, yb));
        std::array::from_fn(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + e[k] * fx) * fy
        })
    }

    /// Each sky cell's mean radiance ([`super::cells`]), the map turned by
    /// `rotate` (the sky's rotation, applied to each direction): the map
    /// as constant texels, each texel cut into `s × s` parts uniform in
    /// `cos θ` and `φ` (equal solid angles), each part's solid angle
    /// credited to the cell of its centre, with `s` chosen so that a
    /// column holds at least [`PARTS_PER_COLUMN`] parts: a texel, however small
    /// (a map's sun), lands in its cell whole, and a large texel is shared
    /// among the cells it spans.
    pub fn cell_means(&self, rotate: impl Fn([f64; 3]) -> [f64; 3]) -> Vec<[f64; 3]> {
        use super::cells::{cell, CELLS};
        let (w, h) = (self.width, self.height);
        let s = PARTS_PER_COLUMN.div_ceil(h).max(1);
        let pi = std::f64::consts::PI;
        let mut sum = vec![[0.0; 3]; CELLS];
        let mut area = vec![0.0; CELLS];
        for y in 0..h {
            let (c0, c1) = (
                (pi * y as f64 / h as f64).cos(),
                (pi * (y + 1) as f64 / h as f64).cos(),
            );
            let omega = 2.0 * pi / w as f64 * (c0 - c1) / (s * s) as f64;
            for i in 0..s {
                let cy = c0 + (c1 - c0) * (i as f64 + 0.5) / s as f64;
                let v = cy.clamp(-1.0, 1.0).acos() / pi;
                for x in 0..w {
                    let l = self.texels[y * w + x];
                    for j in 0..s {
                        let u = (x as f64 + (j as f64 + 0.5) / s as f64) / w as f64;
                        let c = cell(rotate(direction(u, v)));
                        for k in 0..3 {
                            sum[c][k] += f64::from(l[k]) * omega;
                        }
                        area[c] += omega;
                    }
                }
            }
        }
        sum.iter()
            .zip(&area)
            .map(|(l, &a)| if a > 0.0 { l.map(|v| v / a) } else { [0.0; 3] })
            .collect()
    }
}

/// The fewest parts per column of a map in [`LatLong::cell_means`]: 256,
/// 16 per cell's height at the horizon.
pub const PARTS_PER_COLUMN: usize = 256;

/// A loaded map shared by the clones of a sky. Two are equal when they
/// are the same map (one read) or hold the same texels.
#[derive(Clone)]
pub struct Shared(pub Arc<LatLong>);

impl PartialEq for Shared {
    fn eq(&self, other: &Shared) -> bool {
        Arc::ptr_eq(&self.0, &other.0) || *self.0 == *other.0
    }
}

impl std::fmt::Debug for Shared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "LatLong({} x {}, {})",
            self.0.width,
            self.0.height,
            self.0.path.display()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `direction` and `coordinates` invert each other, and the axes sit
    /// where Mitsuba puts them: the top row up, `u = 0.5` towards `+z`,
    /// `u = 0.25` towards `+x`.
    #[test]
    fn coordinates_follow_mitsuba() {
        let near = |a: [f64; 3], b: [f64; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-12);
        assert!(near(direction(0.3, 0.0), [0.0, 1.0, 0.0]));
        assert!(near(direction(0.5, 0.5), [0.0, 0.0, 1.0]));
        assert!(near(direction(0.25, 0.5), [1.0, 0.0, 0.0]));
        assert!(near(direction(0.0, 0.5), [0.0, 0.0, -1.0]));
        for (u, v) in [(0.1, 0.2), (0.6, 0.7), (0.95, 0.4)] {
            let (a, b) = coordinates(direction(u, v));
            assert!((a - u).abs() < 1e-12 && (b - v).abs() < 1e-12);
        }
    }

    /// A constant map has its value as every cell's mean and looks it up
    /// everywhere; a map bright in one texel only puts it in one cell,
    /// whose mean is the texel's radiance times its share of the cell's
    /// solid angle.
    #[test]
    fn a_constant_map_is_the_uniform_sky() {
        let m = LatLong {
            width: 16,
            height: 8,
            texels: vec![[2.0, 1.0, 0.5]; 128],
            path: PathBuf::from("test.pfm"),
            brightest: 2.0,
        };
        for l in m.cell_means(|d| d) {
            for (k, v) in [2.0, 1.0, 0.5].iter().enumerate() {
                assert!((l[k] - v).abs() < 1e-12, "{l:?}");
            }
        }
        assert_eq!(m.lookup([0.3, -0.9, 0.1]), [2.0, 1.0, 0.5]);
    }
}

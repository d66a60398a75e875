//! The optional `SKYV` section: per patch, how it sees the sky — for each
//! sky cell ([`radiosity_core::sky::cells`]) through which rays from the
//! patch's sample points leave the scene, the cell's cosine-weighted
//! visible solid angle: with cosine-weighted rays (pdf `cos/π`),
//! `T_c = π · escaped through c / cast` (the rays cast from the patch,
//! which the covered origins are not). The run time's sky irradiance on
//! the patch is `D_sky = Σ_c L̄_c T_c`.
//! A bake without it (made before skies, or with form factors that cast
//! no rays) loads with none, and the run time says a sky then lights
//! nothing. So does a version-1 section (band-2 harmonics, this project's
//! first sky visibility, superseded on 2026-12-05 for its error: the
//! cells' module doc): bake again.
//!
//! Layout (little-endian): version `u32` (= [`SKY_VERSION`]), cells per
//! side `u32` (= [`SIDE`]), rays drawn per patch `u32`, entries `u32`
//! (`m`); then `n + 1` starts `u32` (patch `i`'s entries are `starts[i] ..
//! starts[i + 1]`, file order), `m` values `T_c` `f32`, and `m` cells `u8`
//! (increasing within a patch).

use crate::section_error::SectionError;
use radiosity_core::sky::cells::{CELLS, SIDE};

/// The layout version this build writes and reads.
pub const SKY_VERSION: u32 = 2;

/// Header bytes before the starts.
const HEADER: usize = 16;

/// Per patch, its cosine-weighted visible solid angle in each sky cell it
/// sees (module doc).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkyVisibility {
    /// Rays drawn per patch (0: no section).
    pub rays: u32,
    /// `n + 1` offsets into `values` and `cells` (empty without a section).
    pub starts: Vec<u32>,
    /// `T_c` of the entry's cell, sr.
    pub values: Vec<f32>,
    /// The entry's cell.
    pub cells: Vec<u8>,
}

impl SkyVisibility {
    /// No sky visibility (a bake made without it).
    pub fn none() -> SkyVisibility {
        SkyVisibility::default()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.rays == 0
    }

    /// From each patch's `(cell, T_c)` list (cells increasing).
    pub fn from_lists(rays: u32, lists: &[Vec<(u8, f32)>]) -> SkyVisibility {
        let mut s = SkyVisibility {
            rays,
            starts: Vec::with_capacity(lists.len() + 1),
            ..SkyVisibility::default()
        };
        s.starts.push(0);
        for l in lists {
            for &(c, k) in l {
                s.cells.push(c);
                s.values.push(k);
            }
            s.starts.push(s.values.len() as u32);
        }
        s
    }

    /// Patch `i`'s `(cell, T_c)`.
    pub fn patch(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (a, b) = (self.starts[i] as usize, self.starts[i + 1] as usize);
        self.cells[a..b]
            .iter()
            .zip(&self.values[a..b])
            .map(|(&c, &t)| (usize::from(c), f64::from(t)))
    }

    /// The section's bytes (module doc).
    pub fn to_bytes(&self) -> Vec<u8> {
        let m = self.values.len();
        let mut out = Vec::with_capacity(HEADER + 4 * self.starts.len() + 5 * m);
        for v in [SKY_VERSION, SIDE as u32, self.rays, m as u32] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in &self.starts {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in &self.values {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.cells);
        out
    }

    /// Reads `SKYV` for a file of `n` patches; every field is checked
    /// ([`SkyVisibility::check`]). A version-1 section reads as none
    /// (module doc).
    pub fn from_bytes(b: &[u8], n: usize) -> Result<SkyVisibility, SectionError> {
        if b.len() < HEADER {
            return Err(SectionError::Truncated {
                what: "header",
                need: HEADER as u64,
                at: 0,
                left: b.len() as u64,
            });
        }
        let u32_at = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"));
        let (version, side, rays, m) = (u32_at(0), u32_at(4), u32_at(8), u32_at(12));
        if version == 1 {
            return Ok(SkyVisibility::none());
        }
        if version != SKY_VERSION || side as usize != SIDE {
            return Err(SectionError::Unsupported(format!(
                "layout version {version} with {side} cells a side; this build reads version \
                 {SKY_VERSION} with {SIDE}"
            )));
        }
        let m = m as u64;
        let expected = HEADER as u64 + 4 * (n as u64 + 1) + 5 * m;
        if b.len() as u64 != expected {
            return Err(SectionError::Length {
                found: b.len() as u64,
                expected,
                layout: format!("{n} patches and {m} entries"),
            });
        }
        let (n1, m) = (n + 1, m as usize);
        let starts = (0..n1).map(|k| u32_at(HEADER + 4 * k)).collect();
        let at = HEADER + 4 * n1;
        let values = (0..m).map(|k| f32::from_bits(u32_at(at + 4 * k))).collect();
        let cells = b[at + 4 * m..].to_vec();
        let s = SkyVisibility {
            rays,
            starts,
            values,
            cells,
        };
        s.check(n)?;
        Ok(s)
    }

    /// Checks the fields: starts from 0 to the entries, never decreasing;
    /// cells in range and increasing within a patch; values finite and
    /// positive, a patch's summing to at most π (the whole hemisphere open)
    /// with the f32 rounding of the sum as slack.
    pub fn check(&self, n: usize) -> Result<(), SectionError> {
        let invalid = |s: String| Err(SectionError::Invalid(s));
        if self.rays == 0 {
            return if self.starts.is_empty() && self.values.is_empty() {
                Ok(())
            } else {
                invalid(format!("{} entries stored for 0 rays", self.values.len()))
            };
        }
        let m = self.values.len();
        if self.starts.len() != n + 1 || self.cells.len() != m {
            return invalid(format!(
                "{} starts and {} cells for {n} patches and {m} entries",
                self.starts.len(),
                self.cells.len()
            ));
        }
        if self.starts[0] != 0 || self.starts[n] as usize != m {
            return invalid(format!(
                "starts run from {} to {}, not 0 to {m}",
                self.starts[0], self.starts[n]
            ));
        }
        for i in 0..n {
            let (a, b) = (self.starts[i] as usize, self.starts[i + 1] as usize);
            if a > b {
                return invalid(format!("patch {i}: starts decrease ({a} > {b})"));
            }
            let mut total = 0.0f64;
            for k in a..b {
                let c = usize::from(self.cells[k]);
                if c >= CELLS || (k > a && self.cells[k] <= self.cells[k - 1]) {
                    return invalid(format!(
                        "patch {i}: cell {c} out of order or beyond {}",
                        CELLS - 1
                    ));
                }
                let t = self.values[k];
                if !(t.is_finite() && t > 0.0) {
                    return invalid(format!("patch {i}: cell {c} has value {t}"));
                }
                total += f64::from(t);
            }
            let pi = std::f64::consts::PI;
            if total > pi * (1.0 + 8.0 * f64::from(f32::EPSILON) * CELLS as f64) {
                return invalid(format!(
                    "patch {i}: its cells sum to {total}, more than the hemisphere's π"
                ));
            }
        }
        Ok(())
    }

    /// The visibility in another patch order: patch `i` of the result is
    /// patch `order[i]` of this one.
    pub fn reordered(&self, order: &[u32]) -> SkyVisibility {
        if self.is_empty() {
            return SkyVisibility::none();
        }
        let lists: Vec<Vec<(u8, f32)>> = order
            .iter()
            .map(|&o| {
                let (a, b) = (
                    self.starts[o as usize] as usize,
                    self.starts[o as usize + 1] as usize,
                );
                self.cells[a..b]
                    .iter()
                    .copied()
                    .zip(self.values[a..b].iter().copied())
                    .collect()
            })
            .collect();
        SkyVisibility::from_lists(self.rays, &lists)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_round_trip_and_faults_are_named() {
        let pi = std::f32::consts::PI;
        let s =
            SkyVisibility::from_lists(64, &[vec![(3, 0.5), (200, 0.25)], vec![], vec![(0, pi)]]);
        let b = s.to_bytes();
        assert_eq!(SkyVisibility::from_bytes(&b, 3).unwrap(), s);
        assert!(matches!(
            SkyVisibility::from_bytes(&b[..10], 3),
            Err(SectionError::Truncated { .. })
        ));
        assert!(matches!(
            SkyVisibility::from_bytes(&b, 4),
            Err(SectionError::Length { .. })
        ));
        let mut newer = b.clone();
        newer[0] = 3;
        assert!(matches!(
            SkyVisibility::from_bytes(&newer, 3),
            Err(SectionError::Unsupported(_))
        ));
        // Version 1 (band-2 harmonics) reads as none.
        let mut older = b.clone();
        older[0] = 1;
        assert!(SkyVisibility::from_bytes(&older, 3).unwrap().is_empty());
        let mut bad = s.clone();
        bad.values[1] = 3.0;
        assert!(bad.check(3).unwrap_err().to_string().contains("patch 0"));
        let mut bad = s.clone();
        bad.cells.swap(0, 1);
        assert!(bad.check(3).unwrap_err().to_string().contains("order"));
        let mut bad = s.clone();
        bad.values[2] = f32::NAN;
        assert!(bad.check(3).is_err());
        let r = s.reordered(&[2, 0, 1]);
        assert_eq!(
            r.patch(0).collect::<Vec<_>>(),
            s.patch(2).collect::<Vec<_>>()
        );
        assert_eq!(r.patch(2).count(), 0);
        assert_eq!(s.patch(2).collect::<Vec<_>>(), vec![(0, f64::from(pi))]);
    }
}

//! The optional `SKYV` section: per patch, how it sees the sky — its
//! band-2 transfer `T_lm = ∫ V(ω) max(0, N·ω) Y_lm(ω) dω`
//! (`radiosity_core::sh`), averaged over the patch's sample points, where
//! `V` is 1 for a direction in which a ray from the point leaves the scene.
//! The run time's sky irradiance on the patch is `D_sky = Σ L_lm T_lm`.
//! A bake without it (made before skies, or with no sky rays) loads with
//! none, and the run time says a sky then lights nothing.
//!
//! Layout (little-endian): version `u32` (= [`SKY_VERSION`]),
//! coefficients per patch `u32` (= [`COEFFICIENTS`]), rays per patch
//! `u32`, reserved `u32` (0), then per patch (file order) its coefficients,
//! `f32` each.

use crate::section_error::SectionError;
use radiosity_core::sh::{self, COEFFICIENTS};

/// The layout version this build writes and reads.
pub const SKY_VERSION: u32 = 1;

/// Header bytes before the coefficients.
const HEADER: usize = 16;

/// Per patch, its sky transfer (module doc).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkyVisibility {
    /// Rays cast per patch (0: no section).
    pub rays: u32,
    /// Per patch, `T_lm` in [`sh::basis`]'s order.
    pub transfer: Vec<[f32; COEFFICIENTS]>,
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

    /// The section's bytes (module doc).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER + 4 * COEFFICIENTS * self.transfer.len());
        for v in [SKY_VERSION, COEFFICIENTS as u32, self.rays, 0] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for t in self.transfer.iter().flatten() {
            out.extend_from_slice(&t.to_le_bytes());
        }
        out
    }

    /// Reads `SKYV` for a file of `n` patches; every field is checked
    /// ([`SkyVisibility::check`]).
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
        let (version, coefficients, rays) = (u32_at(0), u32_at(4), u32_at(8));
        if version != SKY_VERSION || coefficients as usize != COEFFICIENTS {
            return Err(SectionError::Unsupported(format!(
                "layout version {version} with {coefficients} coefficients per patch; this build \
                 reads version {SKY_VERSION} with {COEFFICIENTS}"
            )));
        }
        let expected = HEADER as u64 + 4 * COEFFICIENTS as u64 * n as u64;
        if b.len() as u64 != expected {
            return Err(SectionError::Length {
                found: b.len() as u64,
                expected,
                layout: format!("{n} patches of {COEFFICIENTS} coefficients"),
            });
        }
        let f32_at = |at: usize| f32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"));
        let transfer = (0..n)
            .map(|i| std::array::from_fn(|k| f32_at(HEADER + 4 * (COEFFICIENTS * i + k))))
            .collect();
        let s = SkyVisibility { rays, transfer };
        s.check(n)?;
        Ok(s)
    }

    /// Checks the counts and every coefficient: finite, and the band-0
    /// term within `[0, π Y_00]` (the whole upper hemisphere open), with
    /// the f32 rounding of a sum of `rays` terms as slack.
    pub fn check(&self, n: usize) -> Result<(), SectionError> {
        if self.rays == 0 {
            return if self.transfer.is_empty() {
                Ok(())
            } else {
                Err(SectionError::Invalid(format!(
                    "{} patches' transfer stored for 0 rays",
                    self.transfer.len()
                )))
            };
        }
        if self.transfer.len() != n {
            return Err(SectionError::Invalid(format!(
                "{} patches' transfer for {n} patches",
                self.transfer.len()
            )));
        }
        let open = std::f64::consts::PI * sh::basis([0.0, 1.0, 0.0])[0];
        let slack = open * f64::from(f32::EPSILON) * 8.0 * f64::from(self.rays).sqrt();
        for (i, t) in self.transfer.iter().enumerate() {
            if let Some(k) = t.iter().position(|v| !v.is_finite()) {
                return Err(SectionError::Invalid(format!(
                    "patch {i}: coefficient {k} is {}",
                    t[k]
                )));
            }
            let t0 = f64::from(t[0]);
            if !(-slack..=open + slack).contains(&t0) {
                return Err(SectionError::Invalid(format!(
                    "patch {i}: band-0 transfer {t0} outside [0, π Y_00 = {open:.6}]"
                )));
            }
        }
        Ok(())
    }

    /// The transfer in another patch order: patch `i` of the result is
    /// patch `order[i]` of this one.
    pub fn reordered(&self, order: &[u32]) -> SkyVisibility {
        if self.is_empty() {
            return SkyVisibility::none();
        }
        SkyVisibility {
            rays: self.rays,
            transfer: order.iter().map(|&o| self.transfer[o as usize]).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_round_trip_and_faults_are_named() {
        let s = SkyVisibility {
            rays: 64,
            transfer: vec![[0.5, 0.1, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0; 9]],
        };
        let b = s.to_bytes();
        assert_eq!(SkyVisibility::from_bytes(&b, 2).unwrap(), s);
        assert!(matches!(
            SkyVisibility::from_bytes(&b[..10], 2),
            Err(SectionError::Truncated { .. })
        ));
        assert!(matches!(
            SkyVisibility::from_bytes(&b, 3),
            Err(SectionError::Length { .. })
        ));
        let mut newer = b.clone();
        newer[0] = 2;
        assert!(matches!(
            SkyVisibility::from_bytes(&newer, 2),
            Err(SectionError::Unsupported(_))
        ));
        let mut bad = s.clone();
        bad.transfer[1][0] = 2.0;
        assert!(bad.check(2).unwrap_err().to_string().contains("patch 1"));
        bad.transfer[1][0] = f32::NAN;
        assert!(bad.check(2).is_err());
        assert_eq!(s.reordered(&[1, 0]).transfer[0], s.transfer[1]);
    }
}

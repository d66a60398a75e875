//! The sky: light from every direction at infinity, a light like the
//! others (set per frame in the camera-and-lights file's `"sky"` object, or
//! through the library). Radiance `L(ω)` in W/(m² sr) in metre scenes,
//! linear RGB; the scene's up is `+y`.
//!
//! - `uniform`: `L(ω) = radiance` everywhere (the furnace's sky);
//! - `gradient`: linear in the elevation's sine `s = ω_y` from `horizon`
//!   (s = 0) to `zenith` (s = 1) above the horizon, and to `ground`
//!   (s = −1) below it (light from below stands for a lit ground beyond
//!   the scene).
//!
//! The run time meets a sky through its band-2 spherical harmonics
//! ([`crate::sh`]) and each patch's baked transfer: `D_sky = Σ L_lm T_lm`.

use crate::error::InvalidField;
use crate::sh;
use serde::{Deserialize, Serialize};

/// A sky (module doc).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Sky {
    Uniform {
        radiance: [f32; 3],
    },
    Gradient {
        zenith: [f32; 3],
        horizon: [f32; 3],
        ground: [f32; 3],
    },
}

/// Quadrature rings for a sky's projection ([`sh::project`]): 128 rings
/// of 256 cells (32,768 directions, about 2 ms); the gradient's kink at the
/// horizon is resolved to 1/128 of the sphere's height.
const PROJECTION_RINGS: usize = 128;

impl Sky {
    /// The radiance towards the scene from direction `d` (a unit vector
    /// pointing at the sky).
    pub fn radiance(&self, d: [f64; 3]) -> [f64; 3] {
        match self {
            Sky::Uniform { radiance } => radiance.map(f64::from),
            Sky::Gradient {
                zenith,
                horizon,
                ground,
            } => {
                let s = d[1].clamp(-1.0, 1.0);
                let (far, t) = if s >= 0.0 { (zenith, s) } else { (ground, -s) };
                std::array::from_fn(|k| {
                    f64::from(horizon[k]) + (f64::from(far[k]) - f64::from(horizon[k])) * t
                })
            }
        }
    }

    /// The sky's band-2 coefficients per channel ([`sh::project`]); a
    /// uniform sky's are exact (band 0 only).
    pub fn coefficients(&self) -> [[f64; 3]; sh::COEFFICIENTS] {
        if let Sky::Uniform { radiance } = self {
            let mut c = [[0.0; 3]; sh::COEFFICIENTS];
            // ∫ L Y_00 dω = L · 4π · Y_00.
            let y00 = sh::basis([0.0, 1.0, 0.0])[0];
            c[0] = radiance.map(|r| f64::from(r) * 4.0 * std::f64::consts::PI * y00);
            return c;
        }
        sh::project(|d| self.radiance(d), PROJECTION_RINGS)
    }

    /// Checks every radiance is finite and ≥ 0; the error names the field
    /// (`sky.zenith`, ...) and its value.
    pub fn validate(&self) -> Result<(), InvalidField> {
        let fields: Vec<(&str, &[f32; 3])> = match self {
            Sky::Uniform { radiance } => vec![("radiance", radiance)],
            Sky::Gradient {
                zenith,
                horizon,
                ground,
            } => vec![("zenith", zenith), ("horizon", horizon), ("ground", ground)],
        };
        for (name, v) in fields {
            if !v.iter().all(|x| x.is_finite() && *x >= 0.0) {
                return Err(InvalidField {
                    field: format!("sky.{name}"),
                    value: format!("[{}, {}, {}]", v[0], v[1], v[2]),
                    message: "a radiance must be three finite numbers ≥ 0 (W/(m² sr))".into(),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gradient is the horizon's colour at the horizon and the zenith's
    /// and the ground's at the poles; a gradient of three equal colours is
    /// the uniform sky, coefficient for coefficient (to the quadrature).
    #[test]
    fn a_flat_gradient_is_the_uniform_sky() {
        let g = Sky::Gradient {
            zenith: [1.0, 2.0, 3.0],
            horizon: [0.5, 0.5, 0.5],
            ground: [0.0, 0.0, 0.0],
        };
        assert_eq!(g.radiance([0.0, 1.0, 0.0]), [1.0, 2.0, 3.0]);
        assert_eq!(g.radiance([1.0, 0.0, 0.0]), [0.5, 0.5, 0.5]);
        assert_eq!(g.radiance([0.0, -1.0, 0.0]), [0.0, 0.0, 0.0]);
        let flat = Sky::Gradient {
            zenith: [2.0; 3],
            horizon: [2.0; 3],
            ground: [2.0; 3],
        };
        let u = Sky::Uniform { radiance: [2.0; 3] };
        for (a, b) in flat.coefficients().iter().zip(u.coefficients()) {
            for k in 0..3 {
                assert!(
                    (a[k] - b[k]).abs() < 1e-9 * (1.0 + b[k].abs()),
                    "{a:?} {b:?}"
                );
            }
        }
    }

    #[test]
    fn negative_or_nan_radiance_is_refused_naming_the_field() {
        let s = Sky::Gradient {
            zenith: [1.0; 3],
            horizon: [f32::NAN, 0.0, 0.0],
            ground: [0.0; 3],
        };
        let e = s.validate().unwrap_err();
        assert_eq!(e.field, "sky.horizon");
        let s = Sky::Uniform {
            radiance: [0.0, -1.0, 0.0],
        };
        assert_eq!(s.validate().unwrap_err().field, "sky.radiance");
    }
}

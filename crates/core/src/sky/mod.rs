//! The sky: light from every direction at infinity, a light like the
//! others (set per frame in the camera-and-lights file's `"sky"` object, or
//! through the library). Radiance `L(ω)` in W/(m² sr) in metre scenes,
//! linear RGB; the scene's up is `+y`.
//!
//! - `uniform`: `L(ω) = radiance` everywhere (the furnace's sky);
//! - `gradient`: linear in the elevation's sine `s = ω_y` from `horizon`
//!   (s = 0) to `zenith` (s = 1) above the horizon, and to `ground`
//!   (s = −1) below it (light from below stands for a lit ground beyond
//!   the scene);
//! - `sunsky`: the clear sky of Preetham et al. for the sun towards
//!   `sun_direction` and the atmosphere's `turbidity` (2–10), with its sun,
//!   a directional light ([`Sky::sun`]) the frames add to their lights
//!   ([`preetham`]); both times `intensity`;
//! - `envmap`: a latitude-longitude map from a `.hdr`, `.exr` or `.pfm`
//!   file ([`envmap`]), times `intensity`, turned by `rotation_deg` about
//!   `+y`, right-handed (a positive angle turns the map's `−z` column
//!   towards `−x`: Mitsuba's `<rotate y="1" angle="a"/>` as `to_world`).
//!
//! The run time meets a sky through its mean radiance in each of 256 sky
//! cells ([`cells`], where the choice over spherical harmonics is
//! measured) and each patch's baked visibility: `D_sky = Σ_c L̄_c T_c`.

use crate::error::InvalidField;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub mod cells;
pub mod envmap;
pub mod preetham;

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
    Sunsky {
        /// Towards the sun (need not be unit length).
        sun_direction: [f32; 3],
        turbidity: f32,
        #[serde(default = "one")]
        intensity: f32,
    },
    Envmap {
        /// The map's file, relative to the camera-and-lights file.
        file: PathBuf,
        #[serde(default = "one")]
        intensity: f32,
        #[serde(default)]
        rotation_deg: f32,
        /// The map, read by [`Sky::load_map`] (the camera-and-lights file
        /// does it when read).
        #[serde(skip)]
        map: Option<envmap::Shared>,
    },
}

fn one() -> f32 {
    1.0
}

/// The largest sky radiance accepted, W/(m² sr): its irradiance, `π L` at
/// most, stays within the lights' bound (1e36,
/// `crates/core/src/scene_config.rs`), far from f32's overflow in the
/// frame's sums. A sun and sky's or a map's `intensity` is bounded so that
/// the radiance it scales stays within it (the model's brightest, its sun
/// of about 190 W/m² and a sky near it, is below 1,000 at intensity 1).
pub const MAX_SKY_RADIANCE: f32 = 1e35;

/// A sun and sky's sun ([`Sky::sun`]): the fields of a directional light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// The direction the light travels (from the sun into the scene).
    pub direction: [f32; 3],
    /// W/m² on a surface facing the sun.
    pub irradiance: [f32; 3],
}

impl Sky {
    /// The radiance towards the scene from direction `d` (a unit vector
    /// pointing at the sky). For many directions, [`Sky::prepared`] once.
    pub fn radiance(&self, d: [f64; 3]) -> [f64; 3] {
        self.prepared().radiance(d)
    }

    /// The sky ready to evaluate in many directions: a sun and sky's model
    /// set up for its sun once, a map's rotation once.
    pub fn prepared(&self) -> Prepared<'_> {
        Prepared {
            sky: self,
            preetham: match self {
                Sky::Sunsky {
                    sun_direction,
                    turbidity,
                    ..
                } => Some(preetham::Preetham::new(
                    sun_direction.map(f64::from),
                    f64::from(*turbidity),
                )),
                _ => None,
            },
            // The map turned by +a: look up the direction turned by −a.
            unrotate: match self {
                Sky::Envmap { rotation_deg, .. } => Some(rotation(-f64::from(*rotation_deg))),
                _ => None,
            },
        }
    }

    /// The sky's mean radiance in each sky cell ([`cells`]): a uniform
    /// sky's exactly, a map's texel by texel ([`envmap::LatLong::cell_means`]:
    /// a map's sun can be smaller than a sub-sample's spacing), the others
    /// by [`cells::mean_radiance`].
    pub fn cell_radiance(&self) -> Vec<[f64; 3]> {
        match self {
            Sky::Uniform { radiance } => vec![radiance.map(f64::from); cells::CELLS],
            Sky::Envmap {
                intensity,
                rotation_deg,
                map: Some(m),
                ..
            } => {
                let r = rotation(f64::from(*rotation_deg));
                let k = f64::from(*intensity);
                m.0.cell_means(|d| r.apply(d))
                    .into_iter()
                    .map(|c| c.map(|v| v * k))
                    .collect()
            }
            _ => {
                let p = self.prepared();
                cells::mean_radiance(|d| p.radiance(d))
            }
        }
    }

    /// The sky's sun, for a `sunsky` with its sun above the horizon: a
    /// directional light's direction of travel (away from the sun) and
    /// irradiance, which the frames light the scene with beside their own
    /// lights ([`crate::scene_config::SceneConfig::frame_lights`]).
    pub fn sun(&self) -> Option<Sun> {
        let Sky::Sunsky {
            sun_direction,
            turbidity,
            intensity,
        } = self
        else {
            return None;
        };
        let p = preetham::Preetham::new(sun_direction.map(f64::from), f64::from(*turbidity));
        let e = p
            .sun_irradiance()
            .map(|v| (v * f64::from(*intensity)) as f32);
        (e != [0.0; 3]).then(|| Sun {
            direction: sun_direction.map(|v| -v),
            irradiance: e,
        })
    }

    /// Reads an `envmap` sky's map (`file` relative to `base`, the folder
    /// of the file that names it); other skies have nothing to read.
    pub fn load_map(&mut self, base: &Path) -> Result<(), envmap::EnvMapError> {
        if let Sky::Envmap { file, map, .. } = self {
            let path = base.join(file);
            *map = Some(envmap::Shared(std::sync::Arc::new(envmap::load(&path)?)));
        }
        Ok(())
    }

    /// Whether the sky can be evaluated: every sky but an `envmap` whose
    /// map has not been read ([`Sky::load_map`]).
    pub fn is_ready(&self) -> bool {
        !matches!(self, Sky::Envmap { map: None, .. })
    }
}

/// A sky ready to evaluate ([`Sky::prepared`]).
pub struct Prepared<'a> {
    sky: &'a Sky,
    preetham: Option<preetham::Preetham>,
    unrotate: Option<Rotation>,
}

impl Prepared<'_> {
    /// [`Sky::radiance`].
    pub fn radiance(&self, d: [f64; 3]) -> [f64; 3] {
        match self.sky {
            Sky::Uniform { radiance } => radiance.map(f64::from),
            Sky::Sunsky { intensity, .. } => match &self.preetham {
                Some(p) => p.radiance(d).map(|v| v * f64::from(*intensity)),
                None => [0.0; 3],
            },
            Sky::Envmap { intensity, map, .. } => match (map, &self.unrotate) {
                (Some(m), Some(r)) => m.0.lookup(r.apply(d)).map(|v| v * f64::from(*intensity)),
                _ => [0.0; 3],
            },
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
}

/// Rotation by an angle about `+y`, right-handed (module doc).
#[derive(Clone, Copy, Debug)]
struct Rotation {
    sin: f64,
    cos: f64,
}

impl Rotation {
    fn apply(&self, d: [f64; 3]) -> [f64; 3] {
        let (s, c) = (self.sin, self.cos);
        [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]]
    }
}

/// Rotation by `deg` degrees about `+y` ([`Rotation`]).
fn rotation(deg: f64) -> Rotation {
    let (sin, cos) = deg.to_radians().sin_cos();
    Rotation { sin, cos }
}

impl Sky {
    /// The sky's name in the file's `type` field.
    pub fn kind(&self) -> &'static str {
        match self {
            Sky::Uniform { .. } => "uniform",
            Sky::Gradient { .. } => "gradient",
            Sky::Sunsky { .. } => "sunsky",
            Sky::Envmap { .. } => "envmap",
        }
    }

    /// Checks every radiance is finite and ≥ 0; the error names the field
    /// (`sky.zenith`, ...) and its value.
    pub fn validate(&self) -> Result<(), InvalidField> {
        let bad = |name: &str, value: String, message: &str| InvalidField {
            field: format!("sky.{name}"),
            value,
            message: message.into(),
        };
        let scalar = |name: &str, x: f32, ok: bool, message: &str| {
            if x.is_finite() && ok {
                Ok(())
            } else {
                Err(bad(name, x.to_string(), message))
            }
        };
        let fields: Vec<(&str, &[f32; 3])> = match self {
            Sky::Uniform { radiance } => vec![("radiance", radiance)],
            Sky::Gradient {
                zenith,
                horizon,
                ground,
            } => vec![("zenith", zenith), ("horizon", horizon), ("ground", ground)],
            Sky::Sunsky {
                sun_direction: d,
                turbidity,
                intensity,
            } => {
                if !(d.iter().all(|x| x.is_finite()) && d.iter().any(|x| *x != 0.0)) {
                    return Err(bad(
                        "sun_direction",
                        format!("[{}, {}, {}]", d[0], d[1], d[2]),
                        "the direction towards the sun must be three finite numbers, not all 0",
                    ));
                }
                let t = preetham::TURBIDITY;
                scalar(
                    "turbidity",
                    *turbidity,
                    t.contains(turbidity),
                    &format!(
                        "the turbidity must lie in [{}, {}] (the range of the sky model's fits)",
                        t.start(),
                        t.end()
                    ),
                )?;
                scalar(
                    "intensity",
                    *intensity,
                    *intensity >= 0.0 && *intensity <= MAX_SKY_RADIANCE / 1e3,
                    "the intensity must be a finite number from 0 to 1e32 (beyond, the sky's \
                     light overflows the frame's f32 sums)",
                )?;
                vec![]
            }
            Sky::Envmap {
                intensity,
                rotation_deg,
                map,
                ..
            } => {
                scalar(
                    "intensity",
                    *intensity,
                    *intensity >= 0.0,
                    "the intensity must be a finite number ≥ 0",
                )?;
                // With the map read: its brightest texel times the
                // intensity within the bound.
                let brightest = map.as_ref().map_or(0.0, |m| m.0.brightest);
                if f64::from(brightest) * f64::from(*intensity) > f64::from(MAX_SKY_RADIANCE) {
                    return Err(bad(
                        "intensity",
                        intensity.to_string(),
                        &format!(
                            "the map's brightest texel ({brightest:e}) times the intensity \
                             exceeds 1e35 W/(m² sr): its light would overflow the frame's f32 \
                             sums"
                        ),
                    ));
                }
                scalar(
                    "rotation_deg",
                    *rotation_deg,
                    true,
                    "the rotation must be a finite number of degrees",
                )?;
                vec![]
            }
        };
        for (name, v) in fields {
            if !v
                .iter()
                .all(|x| x.is_finite() && *x >= 0.0 && *x <= MAX_SKY_RADIANCE)
            {
                return Err(bad(
                    name,
                    format!("[{}, {}, {}]", v[0], v[1], v[2]),
                    "a radiance must be three finite numbers from 0 to 1e35 (W/(m² sr))",
                ));
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
    /// the uniform sky, cell for cell.
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
        for (a, b) in flat.cell_radiance().iter().zip(u.cell_radiance()) {
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

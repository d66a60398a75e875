//! The one definition of each light's irradiance at a point (DESIGN.md run
//! time step 2), used by the CPU run time, the bake's error lights, the GLSL
//! shaders (`glsl/light.glsl` mirrors [`incident`] line by line) and the
//! path-tracer export.
//!
//! Units: lengths in the scene's unit; a directional light's `irradiance`
//! is what a surface facing it receives (W per scene unit²: W/m² in metre
//! scenes); spot and point `intensity` is in W/sr, so a point light at
//! distance `r` gives `I cos θ / r²`. Irradiance here is the unshadowed
//! value; [`Incident::shadow_end`] is the point a shadow ray must reach
//! unblocked (the light's position, or a point beyond the scene for a
//! directional light).
//!
//! - **Directional**: `E = irradiance · max(0, n · l)`, `l` = minus the
//!   travel direction, normalised.
//! - **Point**: `E = intensity · max(0, n · l) / r²`.
//! - **Spot**: the point light times the profile of Mitsuba 3's `spot`
//!   emitter: 1 within `beam_angle_deg` of the axis, falling linearly in
//!   angle to 0 at `cone_angle_deg` (a continuous falloff; the path tracer
//!   renders exactly this profile), 0 beyond.
//!
//! Emission (`Ke`) is the exitance of a surface and enters `B0 = ρ ∘ D + E`
//! directly; each emissive material's `Ke` can be scaled at run time (the
//! `emission` map of the camera/lights file).

use crate::core::math::{dot, f64s, normalize, sub};
use crate::core::scene_config::Light;

/// A light's contribution at a point, before shadowing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Irradiance (RGB) on the surface, unshadowed.
    pub irradiance: [f64; 3],
    /// The end of the shadow ray: the light's position, or `x + far · l`.
    pub shadow_end: [f64; 3],
}

/// The spot profile (module doc) at `angle_deg` from the axis.
pub fn spot_profile(angle_deg: f64, cone_deg: f64, beam_deg: f64) -> f64 {
    if angle_deg <= beam_deg {
        1.0
    } else if angle_deg < cone_deg {
        (cone_deg - angle_deg) / (cone_deg - beam_deg)
    } else {
        0.0
    }
}

/// A light with what [`incident`] computes from the light alone done once
/// (f64 values, the normalised direction or axis): per-point work then
/// starts from here, and gives the same bits as from the [`Light`]. Shadow
/// rays cast per sample point and pixel made those normalisations a sixth
/// of a frame's direct light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prepared {
    Directional {
        /// Towards the light: minus the travel direction, normalised.
        l: [f64; 3],
        irradiance: [f64; 3],
    },
    Point {
        position: [f64; 3],
        intensity: [f64; 3],
    },
    Spot {
        position: [f64; 3],
        /// The normalised axis.
        axis: [f64; 3],
        intensity: [f64; 3],
        cone_deg: f64,
        beam_deg: f64,
        /// Cosines of the axis angle beyond which the profile is surely 0
        /// (below `cos_outside`) or surely 1 (above `cos_inside`): the
        /// cosines of the cone and beam angles moved 1e-9 outwards, far
        /// beyond the rounding of `acos` and of the conversion to degrees,
        /// so that most points skip the `acos` (a few per cent of the
        /// direct pass) and get the bits [`spot_profile`] gives.
        cos_outside: f64,
        cos_inside: f64,
    },
}

impl Prepared {
    pub fn new(light: &Light) -> Prepared {
        match *light {
            Light::Directional {
                direction,
                irradiance,
            } => Prepared::Directional {
                l: normalize(f64s(direction)).map(|c| -c),
                irradiance: f64s(irradiance),
            },
            Light::Point {
                position,
                intensity,
            } => Prepared::Point {
                position: f64s(position),
                intensity: f64s(intensity),
            },
            Light::Spot {
                position,
                direction,
                intensity,
                cone_angle_deg,
                beam_angle_deg,
            } => Prepared::Spot {
                position: f64s(position),
                axis: normalize(f64s(direction)),
                intensity: f64s(intensity),
                cone_deg: cone_angle_deg as f64,
                beam_deg: beam_angle_deg as f64,
                cos_outside: (cone_angle_deg as f64).to_radians().cos() - 1e-9,
                cos_inside: (beam_angle_deg as f64).to_radians().cos() + 1e-9,
            },
        }
    }

    /// Every light of `lights`, prepared.
    pub fn all(lights: &[Light]) -> Vec<Prepared> {
        lights.iter().map(Prepared::new).collect()
    }
}

/// The irradiance `light` puts on a surface at `x` with unit normal `n`,
/// unshadowed (module doc); `None` when it is zero (facing away, outside a
/// spot's cone, or no power). `far` is the length of the shadow ray towards
/// a directional light (beyond the scene's extent).
pub fn incident(light: &Light, x: [f64; 3], n: [f64; 3], far: f64) -> Option<Incident> {
    incident_prepared(&Prepared::new(light), x, n, far)
}

/// [`incident`] of a [`Prepared`] light: the one definition.
pub fn incident_prepared(light: &Prepared, x: [f64; 3], n: [f64; 3], far: f64) -> Option<Incident> {
    match *light {
        Prepared::Directional { l, irradiance } => {
            let cos = dot(n, l);
            if !(cos > 0.0) {
                return None;
            }
            Some(Incident {
                irradiance: irradiance.map(|e| e * cos),
                shadow_end: std::array::from_fn(|k| x[k] + far * l[k]),
            })
        }
        Prepared::Point {
            position,
            intensity,
        } => point(x, n, position, intensity, 1.0),
        Prepared::Spot {
            position,
            axis,
            intensity,
            cone_deg,
            beam_deg,
            cos_outside,
            cos_inside,
        } => {
            let from_light = normalize(sub(x, position));
            let c = dot(axis, from_light).clamp(-1.0, 1.0);
            // The angle θ = acos c changes by at least as much as c does,
            // so 1e-9 of c is 1e-9 rad: surely outside the cone, or inside
            // the beam (Prepared::Spot).
            let profile = if c < cos_outside {
                0.0
            } else if c > cos_inside {
                1.0
            } else {
                spot_profile(c.acos().to_degrees(), cone_deg, beam_deg)
            };
            if !(profile > 0.0) {
                return None;
            }
            point(x, n, position, intensity, profile)
        }
    }
}

fn point(
    x: [f64; 3],
    n: [f64; 3],
    pos: [f64; 3],
    intensity: [f64; 3],
    scale: f64,
) -> Option<Incident> {
    let l = sub(pos, x);
    let r2 = dot(l, l);
    if !(r2 > 0.0) {
        return None;
    }
    let cos = dot(n, l) / r2.sqrt();
    if !(cos > 0.0) {
        return None;
    }
    Some(Incident {
        irradiance: intensity.map(|i| scale * i * cos / r2),
        shadow_end: pos,
    })
}

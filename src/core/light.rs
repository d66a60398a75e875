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

/// The irradiance `light` puts on a surface at `x` with unit normal `n`,
/// unshadowed (module doc); `None` when it is zero (facing away, outside a
/// spot's cone, or no power). `far` is the length of the shadow ray towards
/// a directional light (beyond the scene's extent).
pub fn incident(light: &Light, x: [f64; 3], n: [f64; 3], far: f64) -> Option<Incident> {
    match light {
        Light::Directional {
            direction,
            irradiance,
        } => {
            let l = normalize(f64s(*direction)).map(|c| -c);
            let cos = dot(n, l);
            if !(cos > 0.0) {
                return None;
            }
            Some(Incident {
                irradiance: f64s(*irradiance).map(|e| e * cos),
                shadow_end: std::array::from_fn(|k| x[k] + far * l[k]),
            })
        }
        Light::Point {
            position,
            intensity,
        } => point(x, n, f64s(*position), f64s(*intensity), 1.0),
        Light::Spot {
            position,
            direction,
            intensity,
            cone_angle_deg,
            beam_angle_deg,
        } => {
            let pos = f64s(*position);
            let axis = normalize(f64s(*direction));
            let from_light = normalize(sub(x, pos));
            let angle = dot(axis, from_light).clamp(-1.0, 1.0).acos().to_degrees();
            let profile = spot_profile(angle, *cone_angle_deg as f64, *beam_angle_deg as f64);
            if !(profile > 0.0) {
                return None;
            }
            point(x, n, pos, f64s(*intensity), profile)
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

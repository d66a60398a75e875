//! A glTF file's lights (`KHR_lights_punctual`) and first camera as the run
//! time's, converted as module `gltf`'s doc states: photometric to
//! radiometric at [`LUMENS_PER_WATT`], `−z` the direction, `+y` up.

use super::Skipped;
use crate::scene_config::{Camera, Light};
use glam::{DMat4, DVec3};

/// Luminous efficacy used to turn the lights' photometric units into the
/// run time's radiometric ones: 683 lm/W, the maximum (555 nm) by the SI
/// definition of the candela, the factor Blender's glTF importer uses.
pub const LUMENS_PER_WATT: f64 = 683.0;

/// A `KHR_lights_punctual` light at its node (module doc for units).
pub(super) fn convert_light(
    l: &gltf::khr_lights_punctual::Light,
    world: &DMat4,
    skipped: &mut Skipped,
) -> Light {
    if l.range().is_some() {
        skipped.ranges += 1;
    }
    let power = l
        .color()
        .map(|c| (f64::from(c) * f64::from(l.intensity()) / LUMENS_PER_WATT) as f32);
    let position = world.transform_point3(DVec3::ZERO).as_vec3().to_array();
    let direction = world
        .transform_vector3(DVec3::NEG_Z)
        .normalize_or_zero()
        .as_vec3()
        .to_array();
    use gltf::khr_lights_punctual::Kind;
    match l.kind() {
        Kind::Directional => Light::Directional {
            direction,
            irradiance: power,
        },
        Kind::Point => Light::Point {
            position,
            intensity: power,
        },
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => Light::Spot {
            position,
            direction,
            intensity: power,
            cone_angle_deg: outer_cone_angle.to_degrees(),
            beam_angle_deg: inner_cone_angle
                .to_degrees()
                .min(outer_cone_angle.to_degrees()),
        },
    }
}

/// A perspective camera at its node: looking down `−z`, `+y` up; the
/// target a unit ahead (moved once the scene's size is known).
pub(super) fn convert_camera(yfov: f32, world: &DMat4) -> Camera {
    let eye = world.transform_point3(DVec3::ZERO);
    let forward = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
    let up = world.transform_vector3(DVec3::Y).normalize_or_zero();
    Camera {
        position: eye.as_vec3().to_array(),
        target: (eye + forward).as_vec3().to_array(),
        up: up.as_vec3().to_array(),
        fov_y_deg: yfov.to_degrees(),
    }
}

//! The lights as the shaders read them (`crates/gl/glsl/light.glsl`, whose
//! `incident` mirrors [`radiosity_core::light::incident`]) and the views their
//! shadow maps are rendered from:
//!
//! - **directional**: one orthographic view along the light, fitted to the
//!   sphere around the scene's bounds (every caster and receiver inside);
//! - **spot** with a cone up to [`SPOT_MAX_CONE_DEG`]: one perspective
//!   view along its axis whose field of view holds the cone;
//! - **point**, and spots with wider cones: a cube of six perspective
//!   views (layers of the same array), each a little wider than 90° so
//!   that the filter's taps at a face's border stay on that face.
//!
//! Perspective views reach from `1e-3` of the scene's radius to the
//! farthest corner of its bounds. With a 32-bit float depth buffer the
//! depth resolved at distance `z` is about `6e-8 z² / near`: at `z` = the
//! radius, `6e-5` of it, far below a texel (`2 / resolution` of it).

use glam::camera::rh::{proj::opengl, view::look_at_mat4};
use glam::{Mat4, Vec3};
use radiosity_core::scene_config::Light;

/// Widest spot cone (half-angle, degrees) given one view; wider spots get
/// a cube. At 50° the view's texels at the cone's edge are `1 / cos² 51°`
/// = 2.5 times the size of those on the axis.
pub const SPOT_MAX_CONE_DEG: f32 = 50.0;

/// Texels a point is moved along its normal before the shadow lookup
/// (normal-offset shadows), the only slope-dependent bias: the maps are
/// drawn with a constant depth offset of one unit and no slope-scaled
/// offset, because a slope-scaled offset pushes a floor seen at a grazing
/// angle behind the wall standing on it and light leaks into closed rooms
/// along their corners (tests/gl_render.rs,
/// `gl_a_light_outside_a_closed_room_changes_nothing_inside`). 2.5 texels:
/// at 1.5 lit surfaces shadowed themselves (`D` 1.3 % RMS from the CPU's
/// rays on the Cornell box), at 2.5 0.4 %.
pub const NORMAL_OFFSET: f32 = 2.5;

/// Words per light in the `Lights` buffer (four vec4).
pub const LIGHT_WORDS: usize = 16;
/// Words per view in the `Views` buffer (a mat4 and a vec4).
pub const VIEW_WORDS: usize = 20;

/// One shadow map view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowView {
    pub view_projection: Mat4,
    /// World size of a texel (orthographic), or per unit of view depth
    /// (perspective).
    pub texel: f32,
    pub orthographic: bool,
}

/// The packed lights and their views for a scene with bounds `lo..hi`.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Packed {
    /// [`LIGHT_WORDS`] words per light (f32 and i32 bit patterns).
    pub lights: Vec<u32>,
    pub views: Vec<ShadowView>,
}

impl Packed {
    /// Packs `lights` for a scene within `lo..hi`, with shadow maps of
    /// `resolution` texels a side.
    pub fn new(lights: &[Light], lo: [f32; 3], hi: [f32; 3], resolution: usize) -> Packed {
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        let centre = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-30);
        let res = resolution.max(1) as f32;
        let mut out = Packed::default();
        for light in lights {
            let first = out.views.len() as i32;
            let (position, kind, direction, cone, power, beam) = match *light {
                Light::Directional {
                    direction,
                    irradiance,
                } => {
                    let d = unit(direction);
                    let eye = centre - 2.0 * radius * d;
                    let view = look_at_mat4(eye, centre, up_for(d));
                    let proj = opengl::orthographic(
                        -radius,
                        radius,
                        -radius,
                        radius,
                        0.5 * radius,
                        3.5 * radius,
                    );
                    out.views.push(ShadowView {
                        view_projection: proj * view,
                        texel: 2.0 * radius / res,
                        orthographic: true,
                    });
                    ([0.0; 3], 0.0, d.to_array(), 0.0, irradiance, 0.0)
                }
                Light::Point {
                    position,
                    intensity,
                } => {
                    cube(&mut out.views, position.into(), lo, hi, radius, res);
                    (position, 1.0, [0.0, -1.0, 0.0], 0.0, intensity, 0.0)
                }
                Light::Spot {
                    position,
                    direction,
                    intensity,
                    cone_angle_deg,
                    beam_angle_deg,
                } => {
                    let p = Vec3::from(position);
                    let d = unit(direction);
                    if cone_angle_deg <= SPOT_MAX_CONE_DEG {
                        let half = (cone_angle_deg.max(0.0) + 1.0).to_radians();
                        let view = look_at_mat4(p, p + d, up_for(d));
                        let (near, far) = depth_range(p, lo, hi, radius);
                        let proj = opengl::perspective(2.0 * half, 1.0, near, far);
                        out.views.push(ShadowView {
                            view_projection: proj * view,
                            texel: 2.0 * half.tan() / res,
                            orthographic: false,
                        });
                    } else {
                        cube(&mut out.views, p, lo, hi, radius, res);
                    }
                    (
                        position,
                        2.0,
                        d.to_array(),
                        cone_angle_deg,
                        intensity,
                        beam_angle_deg,
                    )
                }
            };
            let count = out.views.len() as i32 - first;
            let f = |v: f32| v.to_bits();
            out.lights.extend_from_slice(&[
                f(position[0]),
                f(position[1]),
                f(position[2]),
                f(kind),
                f(direction[0]),
                f(direction[1]),
                f(direction[2]),
                f(cone),
                f(power[0]),
                f(power[1]),
                f(power[2]),
                f(beam),
                first as u32,
                count as u32,
                0,
                0,
            ]);
        }
        out
    }

    /// The `Views` buffer's words.
    pub fn view_words(&self, resolution: usize) -> Vec<u32> {
        let mut w = Vec::with_capacity(VIEW_WORDS * self.views.len());
        for v in &self.views {
            w.extend(v.view_projection.to_cols_array().map(f32::to_bits));
            w.extend([
                v.texel.to_bits(),
                (if v.orthographic { 1.0f32 } else { 0.0 }).to_bits(),
                (1.0 / resolution.max(1) as f32).to_bits(),
                0,
            ]);
        }
        w
    }
}

/// An up vector not parallel to `d`.
/// A light's direction as a unit vector, normalised in f64: the lights
/// file accepts any finite non-zero direction, and in f32 the squared
/// length of `[1e30, 0, 0]` overflows and that of `[1e-30, 0, 0]`
/// underflows (glam's `normalize_or` then gave its fallback, the shader's
/// `normalize` NaN), where the CPU's f64 definition keeps the direction.
fn unit(direction: [f32; 3]) -> Vec3 {
    let d = radiosity_core::math::normalize(direction.map(f64::from));
    Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32)
}

fn up_for(d: Vec3) -> Vec3 {
    if d.y.abs() < 0.99 {
        Vec3::Y
    } else {
        Vec3::Z
    }
}

/// Near and far planes of a perspective view from `p` (module doc).
fn depth_range(p: Vec3, lo: Vec3, hi: Vec3, radius: f32) -> (f32, f32) {
    let far = (0..8)
        .map(|k| {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            (c - p).length()
        })
        .fold(0.0f32, f32::max);
    let near = 1e-3 * radius;
    (near, (1.01 * far).max(2.0 * near))
}

/// The six cube views of a light at `p` (+x, −x, +y, −y, +z, −z: the face
/// order `visibility` in light.glsl picks by the major axis).
fn cube(views: &mut Vec<ShadowView>, p: Vec3, lo: Vec3, hi: Vec3, radius: f32, res: f32) {
    let (near, far) = depth_range(p, lo, hi, radius);
    // A little wider than 90°: 8 texels of margin on each side.
    let tan_half = 1.0 + 8.0 * 2.0 / res;
    let proj = opengl::perspective(2.0 * tan_half.atan(), 1.0, near, far);
    let faces = [
        (Vec3::X, Vec3::NEG_Y),
        (Vec3::NEG_X, Vec3::NEG_Y),
        (Vec3::Y, Vec3::Z),
        (Vec3::NEG_Y, Vec3::NEG_Z),
        (Vec3::Z, Vec3::NEG_Y),
        (Vec3::NEG_Z, Vec3::NEG_Y),
    ];
    for (d, up) in faces {
        views.push(ShadowView {
            view_projection: proj * look_at_mat4(p, p + d, up),
            texel: 2.0 * tan_half / res,
            orthographic: false,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A direction given at any scale packs as the same unit vector and
    /// the same shadow views as at scale 1, bit for bit (f32 normalisation
    /// overflowed at 1e30 and underflowed at 1e-30 per component).
    #[test]
    fn directions_at_any_scale_pack_the_same() {
        let (lo, hi) = ([0.0; 3], [10.0, 4.0, 6.0]);
        let lights = |s: f32| {
            vec![
                Light::Directional {
                    direction: [0.3 * s, -s, 0.2 * s],
                    irradiance: [1.0; 3],
                },
                Light::Spot {
                    position: [5.0, 3.5, 3.0],
                    direction: [0.1 * s, -s, -0.2 * s],
                    intensity: [2.0; 3],
                    cone_angle_deg: 30.0,
                    beam_angle_deg: 20.0,
                },
                Light::Spot {
                    position: [5.0, 3.5, 3.0],
                    direction: [-0.4 * s, -s, 0.0],
                    intensity: [2.0; 3],
                    cone_angle_deg: 80.0,
                    beam_angle_deg: 60.0,
                },
            ]
        };
        let one = Packed::new(&lights(1.0), lo, hi, 512);
        // Powers of two, so that the scaled inputs are exact: 2^±100 is
        // about 1e±30, whose squares leave f32's range.
        for s in [-100, -70, 70, 100].map(|k| 2f32.powi(k)) {
            assert_eq!(Packed::new(&lights(s), lo, hi, 512), one, "scale {s}");
        }
        // The packed directions are unit vectors.
        for l in one.lights.chunks(LIGHT_WORDS) {
            let d = [4, 5, 6].map(|k| f32::from_bits(l[k]));
            let len = d.iter().map(|v| v * v).sum::<f32>().sqrt();
            assert!((len - 1.0).abs() < 1e-6, "{d:?}");
        }
    }
}

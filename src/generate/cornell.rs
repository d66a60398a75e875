//! The Cornell box from its published measurements: Cornell Program of
//! Computer Graphics, "Cornell Box Data",
//! <https://www.graphics.cornell.edu/online/box/data.html>. Coordinates are
//! those of the page, in millimetres, kept exactly (every published vertex is
//! a vertex of the mesh); surfaces are tessellated into cells of at most
//! `MAX_CELL` between them.
//!
//! The ceiling has the published hole (343..213 × 227..332) and the light
//! quad fills it exactly at the published height y = 548.8, so the light and
//! the ceiling are coplanar without overlapping and no coordinate is moved.

use super::mesh::MeshBuilder;
use super::{assemble, GeneratedScene};
use crate::core::scene_config::{Camera, Light, SceneConfig};
use glam::DVec3;

/// Decimals written for this scene (published values have one).
pub(super) const DECIMALS: u32 = 4;
/// The largest cell edge, in millimetres.
pub(super) const MAX_CELL: f64 = 50.0;

/// Published vertex lists (Cornell Box Data), in the page's order.
pub(super) const FLOOR: [[f64; 3]; 4] = [
    [552.8, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 559.2],
    [549.6, 0.0, 559.2],
];
/// The light, and also the hole in the ceiling.
pub(super) const LIGHT: [[f64; 3]; 4] = [
    [343.0, 548.8, 227.0],
    [343.0, 548.8, 332.0],
    [213.0, 548.8, 332.0],
    [213.0, 548.8, 227.0],
];
pub(super) const CEILING: [[f64; 3]; 4] = [
    [556.0, 548.8, 0.0],
    [556.0, 548.8, 559.2],
    [0.0, 548.8, 559.2],
    [0.0, 548.8, 0.0],
];
pub(super) const BACK_WALL: [[f64; 3]; 4] = [
    [549.6, 0.0, 559.2],
    [0.0, 0.0, 559.2],
    [0.0, 548.8, 559.2],
    [556.0, 548.8, 559.2],
];
/// The green wall, at x = 0 (on the right as seen by the camera).
pub(super) const RIGHT_WALL: [[f64; 3]; 4] = [
    [0.0, 0.0, 559.2],
    [0.0, 0.0, 0.0],
    [0.0, 548.8, 0.0],
    [0.0, 548.8, 559.2],
];
/// The red wall, near x = 556 (on the left as seen by the camera). It is not
/// planar in the published data (its corners leave any plane by about
/// 3 mm); the tessellation follows the bilinear surface through them.
pub(super) const LEFT_WALL: [[f64; 3]; 4] = [
    [552.8, 0.0, 0.0],
    [549.6, 0.0, 559.2],
    [556.0, 548.8, 559.2],
    [556.0, 548.8, 0.0],
];
/// The short block's top footprint (x, z) and height.
pub(super) const SHORT_BLOCK: ([[f64; 2]; 4], f64) = (
    [[130.0, 65.0], [82.0, 225.0], [240.0, 272.0], [290.0, 114.0]],
    165.0,
);
/// The tall block's top footprint (x, z) and height.
pub(super) const TALL_BLOCK: ([[f64; 2]; 4], f64) = (
    [
        [423.0, 247.0],
        [265.0, 296.0],
        [314.0, 456.0],
        [472.0, 406.0],
    ],
    330.0,
);

/// Linear RGB albedos: the RGB fits of the measured spectra used by the
/// Mitsuba and pbrt versions of the box.
const WHITE: [f32; 3] = [0.725, 0.71, 0.68];
const RED: [f32; 3] = [0.63, 0.065, 0.05];
const GREEN: [f32; 3] = [0.14, 0.45, 0.091];
const LIGHT_KD: [f32; 3] = [0.78, 0.78, 0.78];
/// The light's emission, as in the common path-tracing versions of the box.
pub(super) const LIGHT_KE: [f32; 3] = [17.0, 12.0, 4.0];

fn v(p: [f64; 3]) -> DVec3 {
    DVec3::from_array(p)
}

fn quad(b: &mut MeshBuilder, q: [[f64; 3]; 4], facing: DVec3) {
    b.quad([v(q[0]), v(q[1]), v(q[2]), v(q[3])], facing);
}

/// A block: the top and the four sides (the bottom rests on the floor and
/// is not modelled), all facing outwards. The side faces are the published
/// ones: each joins two consecutive top corners to the floor.
fn block(b: &mut MeshBuilder, (top, h): ([[f64; 2]; 4], f64)) {
    let p = |i: usize, y: f64| DVec3::new(top[i][0], y, top[i][1]);
    let centre = (0..4).map(|i| p(i, 0.0)).sum::<DVec3>() / 4.0;
    b.quad([p(0, h), p(1, h), p(2, h), p(3, h)], DVec3::Y);
    for i in 0..4 {
        let j = (i + 1) % 4;
        let out = (p(i, 0.0) + p(j, 0.0)) * 0.5 - centre;
        b.quad([p(i, 0.0), p(i, h), p(j, h), p(j, 0.0)], out);
    }
}

/// The x and z ranges and the height of a horizontal axis-aligned
/// rectangle given by its corners.
fn xz_rect(q: &[[f64; 3]; 4]) -> ((f64, f64), (f64, f64), f64) {
    let min = |k: usize| q.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
    let max = |k: usize| q.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max);
    assert!(min(1) == max(1), "not horizontal");
    ((min(0), max(0)), (min(2), max(2)), q[0][1])
}

/// The camera's vertical field of view from the published focal length
/// (0.035) and film size (0.025 × 0.025): 2·atan(0.0125 / 0.035), degrees.
pub(super) fn fov_y_deg() -> f32 {
    (2.0 * (0.0125f64 / 0.035).atan()).to_degrees() as f32
}

pub(super) fn build() -> Result<GeneratedScene, usize> {
    build_with("cornell_box", MAX_CELL)
}

/// The box from the published data with cells of at most `max_cell`
/// millimetres (`f64::INFINITY`: the published quads untessellated, as a
/// user's export would have them), written as `name`.
pub(super) fn build_with(name: &str, max_cell: f64) -> Result<GeneratedScene, usize> {
    let mut b = MeshBuilder::new(DECIMALS, max_cell);
    let white = b.material("white", WHITE, [0.0; 3]);
    let red = b.material("red", RED, [0.0; 3]);
    let green = b.material("green", GREEN, [0.0; 3]);
    let light = b.material("light", LIGHT_KD, LIGHT_KE);

    b.set_material(white);
    quad(&mut b, FLOOR, DVec3::Y);
    quad(&mut b, BACK_WALL, -DVec3::Z);
    // The ceiling is an axis-aligned rectangle minus the light's hole;
    // cutting at the hole's edges keeps it conforming with the light quad.
    let (ceiling_x, ceiling_z, y) = xz_rect(&CEILING);
    let (light_x, light_z, _) = xz_rect(&LIGHT);
    let hole = [light_x.0, light_x.1, light_z.0, light_z.1];
    b.plane_with_holes(1, y, -1.0, ceiling_x, ceiling_z, &[hole]);
    block(&mut b, SHORT_BLOCK);
    block(&mut b, TALL_BLOCK);
    b.set_material(red);
    quad(&mut b, LEFT_WALL, -DVec3::X);
    b.set_material(green);
    quad(&mut b, RIGHT_WALL, DVec3::X);
    b.set_material(light);
    b.plane_rect(1, y, -1.0, light_x, light_z);

    let area = 130.0 * 105.0;
    let intensity = LIGHT_KE.map(|e| (e as f64 * area / std::f64::consts::PI) as f32);
    let config = SceneConfig {
        sky: None,
        objects: Vec::new(),
        emission: Default::default(),
        camera: Camera {
            position: [278.0, 273.0, -800.0],
            target: [278.0, 273.0, -799.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: fov_y_deg(),
        },
        lights: vec![Light::Spot {
            position: [278.0, 548.0, 279.5],
            direction: [0.0, -1.0, 0.0],
            intensity,
            cone_angle_deg: 60.0,
            beam_angle_deg: 45.0,
        }],
        units: "mm".into(),
        description: "Cornell box from the Cornell Box Data page \
            (https://www.graphics.cornell.edu/online/box/data.html), millimetres. \
            Camera from the data: eye (278, 273, -800) looking along +z, focal length 35 mm, \
            film 25 mm. The scene is also lit by the emissive quad `light` \
            (Ke 17 12 4, 130 x 105 mm at y = 548.8, filling the ceiling hole, facing down). \
            The spot light 0.8 mm below the quad's centre, pointing down, is its dynamic \
            stand-in: intensity = Ke * 13650 mm^2 / pi, the on-axis intensity of the quad \
            when Ke is read as its exitance. Both are on: for the spot alone set \
            \"emission\": {\"light\": 0} (or press M in the viewer); for the quad alone \
            remove the spot."
            .into(),
    };
    assemble(
        name,
        &[
            "Cornell box: Cornell Program of Computer Graphics, \"Cornell Box Data\",",
            "https://www.graphics.cornell.edu/online/box/data.html (published coordinates kept exactly).",
            "Units: millimetres. Generated by `radiosity generate cornell_box`; do not edit.",
        ],
        DECIMALS as usize,
        b,
        config,
    )
}

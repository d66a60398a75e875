//! Scenes that are not kind, for the accuracy tests and reports (generated
//! on demand, not committed): big untessellated quads, sizes that do not
//! divide a voxel grid, surfaces covered by others, thin walls.
//!
//! - `cornell_panel`: a Cornell box of other provenance, in metres: a 1 m
//!   box open at the front, each wall one quad (two triangles), a 0.3 m
//!   square light panel 1 cm below the ceiling (the ceiling above it is
//!   hidden), two blocks rotated by ±17° standing on the floor without
//!   bottoms (the floor under them is hidden), Cornell albedos, the panel
//!   emitting `Ke` = (17, 12, 4).
//! - `cornell_published`: the Cornell box from its published data in
//!   millimetres with the published quads untessellated (the bundled one
//!   is tessellated into 5 cm cells), as a user's export would have it.
//! - `two_rooms`: two closed 2 × 1 × 1 m rooms sharing a wall 2 cm thick
//!   (from x = 2.01 to 2.03, so that no usual voxel grid aligns with it),
//!   each face one quad; the left room's ceiling glows (`Ke` 5), the right
//!   room has no light.
//! - `odd_box`: a closed box 1.37 × 0.83 × 2.11 m, faces inwards, one quad
//!   each, albedo 0.9 and `Ke` 1 everywhere: the furnace, with sides that
//!   divide no voxel size.
//! - `cluttered_room`: a 12 × 8 × 3.5 m room, each face one quad, lit by
//!   a 2 × 2 m ceiling panel 1 cm under the ceiling (`Ke` 20), full of
//!   things far smaller than a patch: a railing of 80 balusters (4 cm
//!   square, 90 cm tall, 12 cm apart) under a hand rail, 12 chairs (seat,
//!   four 3 cm legs, back), 150 blocks of 5 to 15 cm on the floor and 40
//!   parts hanging in the air (a lamp's bits). Clutter is 10 % of the
//!   area; a patch budget spent on its fragments leaves the floor and the
//!   walls a few huge patches (issue 42).

use super::mesh::MeshBuilder;
use super::{assemble, GeneratedScene};
use crate::core::scene_config::{Camera, SceneConfig};
use glam::DVec3;

/// Coordinates are written with 5 decimals (10 µm in these metre scenes).
const DECIMALS: u32 = 5;
/// No tessellation: every face is one quad.
const NO_CELLS: f64 = 1e9;

/// The inward faces of the box `[lo, hi]` (skipping those in `skip`:
/// bits as the box helpers', by the face's position −x, +x, −y, …).
fn room(b: &mut MeshBuilder, lo: DVec3, hi: DVec3, skip: u8) {
    let c = (lo + hi) * 0.5;
    let h = (hi - lo) * 0.5;
    for k in 0..3 {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        for (bit, s) in [(2 * k, -1.0f64), (2 * k + 1, 1.0)] {
            if skip & (1 << bit) != 0 {
                continue;
            }
            let mut hk = DVec3::ZERO;
            hk[k] = h[k] * s;
            let (mut hi_, mut hj) = (DVec3::ZERO, DVec3::ZERO);
            hi_[i] = h[i];
            hj[j] = h[j];
            let f = c + hk;
            let corners = [f - hi_ - hj, f + hi_ - hj, f + hi_ + hj, f - hi_ + hj];
            b.quad(corners, -hk);
        }
    }
}

fn camera(position: [f32; 3], target: [f32; 3], fov: f32) -> Camera {
    Camera {
        position,
        target,
        up: [0.0, 1.0, 0.0],
        fov_y_deg: fov,
    }
}

fn config(camera: Camera, description: &str) -> SceneConfig {
    SceneConfig {
        sky: None,
        objects: Vec::new(),
        emission: Default::default(),
        camera,
        lights: Vec::new(),
        units: "m".into(),
        description: description.into(),
    }
}

pub(super) fn cornell_panel() -> Result<GeneratedScene, usize> {
    let mut b = MeshBuilder::new(DECIMALS, NO_CELLS);
    let white = b.material("white", [0.725, 0.71, 0.68], [0.0; 3]);
    let red = b.material("red", [0.63, 0.065, 0.05], [0.0; 3]);
    let green = b.material("green", [0.14, 0.45, 0.091], [0.0; 3]);
    let light = b.material("light", [0.78, 0.78, 0.78], [17.0, 12.0, 4.0]);
    let (x0, x1, y0, y1, z0, z1) = (0.0, 1.0, 0.0, 1.0, 0.0, 1.0);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    b.set_material(white);
    b.quad(
        [p(x0, y0, z0), p(x0, y0, z1), p(x1, y0, z1), p(x1, y0, z0)],
        DVec3::Y,
    );
    b.quad(
        [p(x0, y1, z0), p(x1, y1, z0), p(x1, y1, z1), p(x0, y1, z1)],
        -DVec3::Y,
    );
    b.quad(
        [p(x0, y0, z1), p(x0, y1, z1), p(x1, y1, z1), p(x1, y0, z1)],
        -DVec3::Z,
    );
    b.set_material(red);
    b.quad(
        [p(x0, y0, z0), p(x0, y1, z0), p(x0, y1, z1), p(x0, y0, z1)],
        DVec3::X,
    );
    b.set_material(green);
    b.quad(
        [p(x1, y0, z0), p(x1, y0, z1), p(x1, y1, z1), p(x1, y1, z0)],
        -DVec3::X,
    );
    b.set_material(light);
    let y = 0.99;
    b.quad(
        [
            p(0.35, y, 0.35),
            p(0.65, y, 0.35),
            p(0.65, y, 0.65),
            p(0.35, y, 0.65),
        ],
        -DVec3::Y,
    );
    b.set_material(white);
    // Blocks: all faces but the bottom (bit 2: towards −y).
    let rot = |deg: f64, v: DVec3| {
        let (s, c) = deg.to_radians().sin_cos();
        DVec3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z)
    };
    let mask = 63 & !(1 << 2);
    let short = [
        rot(-17.0, DVec3::new(0.15, 0.0, 0.0)),
        DVec3::new(0.0, 0.15, 0.0),
        rot(-17.0, DVec3::new(0.0, 0.0, 0.15)),
    ];
    b.oriented_box(DVec3::new(0.68, 0.15, 0.35), short, mask);
    let tall = [
        rot(17.0, DVec3::new(0.15, 0.0, 0.0)),
        DVec3::new(0.0, 0.3, 0.0),
        rot(17.0, DVec3::new(0.0, 0.0, 0.15)),
    ];
    b.oriented_box(DVec3::new(0.32, 0.3, 0.65), tall, mask);
    assemble(
        "cornell_panel",
        &["A Cornell box of other provenance: 1 m, open front, untessellated walls,",
          "a light panel 1 cm below the ceiling, rotated blocks without bottoms."],
        DECIMALS as usize,
        b,
        config(
            camera([0.5, 0.5, -1.4], [0.5, 0.5, 0.5], 39.3),
            "The panel light alone (emission); the ceiling above the panel and the floor under the blocks are hidden.",
        ),
    )
}

pub(super) fn two_rooms() -> Result<GeneratedScene, usize> {
    let mut b = MeshBuilder::new(DECIMALS, NO_CELLS);
    let plain = b.material("plaster", [0.7, 0.7, 0.7], [0.0; 3]);
    let glow = b.material("glow", [0.7, 0.7, 0.7], [5.0, 5.0, 5.0]);
    let (w0, w1) = (2.01, 2.03);
    b.set_material(plain);
    // The left room without its ceiling, then the glowing ceiling.
    room(&mut b, DVec3::ZERO, DVec3::new(w0, 1.0, 1.0), 1 << 3);
    b.set_material(glow);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    b.quad(
        [
            p(0.0, 1.0, 0.0),
            p(w0, 1.0, 0.0),
            p(w0, 1.0, 1.0),
            p(0.0, 1.0, 1.0),
        ],
        -DVec3::Y,
    );
    b.set_material(plain);
    room(
        &mut b,
        DVec3::new(w1, 0.0, 0.0),
        DVec3::new(w1 + 2.0, 1.0, 1.0),
        0,
    );
    assemble(
        "two_rooms",
        &["Two closed rooms sharing a 2 cm wall (x 2.01..2.03); light only in the left one."],
        DECIMALS as usize,
        b,
        config(
            camera([3.9, 0.5, 0.1], [2.03, 0.4, 0.6], 70.0),
            "The camera stands in the dark room looking at the shared wall.",
        ),
    )
}

pub(super) fn odd_box() -> Result<GeneratedScene, usize> {
    let mut b = MeshBuilder::new(DECIMALS, NO_CELLS);
    let m = b.material("furnace", [0.9, 0.9, 0.9], [1.0, 1.0, 1.0]);
    b.set_material(m);
    room(&mut b, DVec3::ZERO, DVec3::new(1.37, 0.83, 2.11), 0);
    assemble(
        "odd_box",
        &["A closed box 1.37 x 0.83 x 2.11 m, inward faces, albedo 0.9, Ke 1: the furnace."],
        DECIMALS as usize,
        b,
        config(
            camera([0.685, 0.415, 0.2], [0.685, 0.415, 2.0], 70.0),
            "Exact irradiance from emission: E / (1 - rho) = 10 everywhere.",
        ),
    )
}

/// A deterministic stream in [0, 1) (an LCG: the scene must not depend on
/// a random crate's version).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

pub(super) fn cluttered_room() -> Result<GeneratedScene, usize> {
    let mut b = MeshBuilder::new(DECIMALS, NO_CELLS);
    let wall = b.material("wall", [0.7, 0.7, 0.7], [0.0; 3]);
    let floor = b.material("floor", [0.5, 0.4, 0.3], [0.0; 3]);
    let wood = b.material("wood", [0.6, 0.35, 0.2], [0.0; 3]);
    let metal = b.material("metal", [0.4, 0.4, 0.45], [0.0; 3]);
    let light = b.material("light", [0.8, 0.8, 0.8], [20.0, 20.0, 20.0]);
    let (w, d, h) = (12.0, 8.0, 3.5);
    b.set_material(wall);
    // Walls and ceiling (bit 2 is the floor, −y).
    room(&mut b, DVec3::ZERO, DVec3::new(w, h, d), 1 << 2);
    b.set_material(floor);
    room(&mut b, DVec3::ZERO, DVec3::new(w, h, d), !(1 << 2));
    // The light panel: a thin box under the ceiling, all faces.
    b.set_material(light);
    b.axis_box(
        DVec3::new(5.0, h - 0.03, 3.0),
        DVec3::new(7.0, h - 0.01, 5.0),
        0x3f,
    );
    // The railing along x at z = 2: balusters and a hand rail on top.
    b.set_material(metal);
    for k in 0..80 {
        let x = 1.2 + 0.12 * k as f64;
        b.axis_box(
            DVec3::new(x, 0.0, 1.98),
            DVec3::new(x + 0.04, 0.9, 2.02),
            0x3f & !(1 << 2),
        );
    }
    b.axis_box(
        DVec3::new(1.1, 0.9, 1.96),
        DVec3::new(10.8, 0.96, 2.04),
        0x3f,
    );
    // Chairs: 4 × 3 in the far half of the room.
    b.set_material(wood);
    for i in 0..4 {
        for j in 0..3 {
            let (x, z) = (2.0 + 2.4 * i as f64, 3.5 + 1.4 * j as f64);
            b.axis_box(
                DVec3::new(x, 0.45, z),
                DVec3::new(x + 0.45, 0.49, z + 0.45),
                0x3f,
            );
            for (lx, lz) in [(0.0, 0.0), (0.42, 0.0), (0.0, 0.42), (0.42, 0.42)] {
                b.axis_box(
                    DVec3::new(x + lx, 0.0, z + lz),
                    DVec3::new(x + lx + 0.03, 0.45, z + lz + 0.03),
                    0x3f & !(1 << 2) & !(1 << 3),
                );
            }
            b.axis_box(
                DVec3::new(x, 0.49, z + 0.42),
                DVec3::new(x + 0.45, 1.0, z + 0.45),
                0x3f & !(1 << 2),
            );
        }
    }
    // Blocks on the floor and parts in the air, placed by a fixed stream
    // (the chairs' and the railing's places avoided only loosely: overlaps
    // are what users' models have).
    let mut r = Lcg(42);
    b.set_material(wood);
    for _ in 0..150 {
        let s = 0.05 + 0.1 * r.next();
        let (x, z) = (0.5 + 11.0 * r.next(), 0.5 + 7.0 * r.next());
        b.axis_box(
            DVec3::new(x, 0.0, z),
            DVec3::new(x + s, s, z + s),
            0x3f & !(1 << 2),
        );
    }
    b.set_material(metal);
    for _ in 0..40 {
        let s = 0.03 + 0.07 * r.next();
        let c = DVec3::new(
            1.0 + 10.0 * r.next(),
            2.0 + 1.0 * r.next(),
            1.0 + 6.0 * r.next(),
        );
        b.axis_box(c, c + DVec3::splat(s), 0x3f);
    }
    assemble(
        "cluttered_room",
        &[
            "A 12 x 8 x 3.5 m room full of things far smaller than a patch: 80 balusters,",
            "12 chairs, 150 blocks on the floor, 40 parts in the air; a ceiling panel lights it.",
        ],
        DECIMALS as usize,
        b,
        config(
            camera([0.6, 1.7, 7.4], [8.0, 0.6, 1.0], 70.0),
            "The camera looks across the chairs at the railing and the floor.",
        ),
    )
}

//! An architectural interior at the scale of the thesis's test scenes
//! (50,000–100,000 triangles), in metres, built from axis-aligned rooms.
//!
//! Plan (x east, y up, z south; exterior footprint 18 × 12 m):
//! - the hall, x 0.2–9.9, z 0.2–7.9, 7 m high, with a mezzanine along its
//!   north wall (floor at 3.5 m) carried by an arcade of four semicircular
//!   arches on three columns, and a straight stair of 20 risers up to it;
//! - the dining room, x 0.2–9.9, z 8.1–11.8, 3.5 m high;
//! - the living room, x 10.1–17.8, z 0.2–5.9, 3.5 m high;
//! - the bedroom, x 10.1–17.8, z 6.1–11.8, 3.5 m high.
//!
//! Walls are 0.2 m thick and both their sides are modelled: each room's
//! inner faces, the exterior faces of the outer walls, and the reveals
//! (jambs, sills, heads) of every door and window through the thickness.
//! Faces hidden by contact (a wall behind the stair, the floor under a
//! rug, the ceiling above a lamp) are cut out rather than modelled. The
//! roofs close the shell (so the sun's shadow map sees an opaque building
//! whichever faces it culls); the ground under the floors is not modelled.
//! Every surface is tessellated into cells of at most 0.25 m, because the
//! renderer lights vertices, which is also what brings the scene to its
//! triangle count; only the roofs, which nothing inside sees, use 0.5 m.

use super::mesh::{MeshBuilder, ALL, NX, NY, NZ, PX, PY, PZ};
use super::{assemble, GeneratedScene};
use crate::core::scene_config::{Camera, Light, SceneConfig};
use glam::DVec3;

mod rooms;
use rooms::{bedroom, dining, hall, living};

/// Millimetre-and-a-tenth precision keeps the file small.
const DECIMALS: u32 = 4;
/// The largest cell edge, in metres.
const MAX_CELL: f64 = 0.25;
/// The roofs' cells: only the sun and outside views see the roofs.
const ROOF_CELL: f64 = 0.5;

/// The hall's height (ceiling), and the other rooms'.
const HALL_H: f64 = 7.0;
const ROOM_H: f64 = 3.5;
/// Roof slabs are 0.2 m thick: the exterior walls rise to these heights.
const HALL_TOP: f64 = 7.2;
const WING_TOP: f64 = 3.7;

/// The mezzanine slab: underside, top, and its front edge (z).
const MEZZ_BOTTOM: f64 = 3.3;
const MEZZ_TOP: f64 = 3.5;
const MEZZ_FRONT: f64 = 3.2;
/// The arcade wall under the mezzanine's front edge spans z 2.9–3.2 and x
/// from the stair's pier (x = 1.6) to the east wall (x = 9.9) in four bays.
const ARCADE_Z: (f64, f64) = (2.9, 3.2);
const ARCADE_X: (f64, f64) = (1.6, 9.9);
const BAYS: usize = 4;
/// Width of the masonry between an arch and the end of its bay.
const PIER_HALF: f64 = 0.2;
/// The arches' springing height: their crowns sit 0.2 m under the slab.
fn arch_radius() -> f64 {
    (ARCADE_X.1 - ARCADE_X.0) / BAYS as f64 / 2.0 - PIER_HALF
}
fn spring() -> f64 {
    MEZZ_BOTTOM - 0.2 - arch_radius()
}

/// The stair: 20 risers of 0.175 m and 19 treads of 0.22 m, 1.2 m wide
/// along the west wall, climbing north to the mezzanine's front edge.
const STAIR_RISERS: usize = 20;
const STAIR_RISE: f64 = 0.175;
const STAIR_RUN: f64 = 0.22;
const STAIR_X: (f64, f64) = (0.2, 1.4);
fn stair_foot_z() -> f64 {
    MEZZ_FRONT + STAIR_RUN * (STAIR_RISERS - 1) as f64
}

/// An opening through a wall: the wall is perpendicular to `axis` (0 = x,
/// 2 = z) and spans `t` along it; the opening spans `a` along the wall (z
/// for x-walls, x for z-walls) and `y` in height.
struct Opening {
    axis: usize,
    t: (f64, f64),
    a: (f64, f64),
    y: (f64, f64),
}

const fn door(axis: usize, t: (f64, f64), a: (f64, f64), h: f64) -> Opening {
    Opening {
        axis,
        t,
        a,
        y: (0.0, h),
    }
}

const fn window(axis: usize, t: (f64, f64), a: (f64, f64), y: (f64, f64)) -> Opening {
    Opening { axis, t, a, y }
}

/// Every door and window of the building.
const OPENINGS: &[Opening] = &[
    // Doors between rooms.
    door(0, (9.9, 10.1), (4.4, 5.4), 2.2), // hall – living room
    door(2, (7.9, 8.1), (4.0, 6.0), 2.5),  // hall – dining room
    door(2, (5.9, 6.1), (15.5, 16.5), 2.2), // living room – bedroom
    door(0, (9.9, 10.1), (10.0, 11.0), 2.2), // dining room – bedroom
    // Hall: north wall, two storeys of windows; west wall, one under the
    // mezzanine and a tall one above the stair.
    window(2, (0.0, 0.2), (2.5, 4.0), (0.9, 2.6)),
    window(2, (0.0, 0.2), (6.0, 7.5), (0.9, 2.6)),
    window(2, (0.0, 0.2), (2.5, 4.0), (4.2, 6.4)),
    window(2, (0.0, 0.2), (6.0, 7.5), (4.2, 6.4)),
    window(0, (0.0, 0.2), (1.0, 2.2), (0.9, 2.6)),
    window(0, (0.0, 0.2), (4.2, 6.6), (4.4, 6.4)),
    // Living room: north and east.
    window(2, (0.0, 0.2), (11.5, 13.5), (0.9, 2.4)),
    window(2, (0.0, 0.2), (15.0, 17.0), (0.9, 2.4)),
    window(0, (17.8, 18.0), (2.0, 4.5), (0.9, 2.4)),
    // Bedroom: east and south.
    window(0, (17.8, 18.0), (8.0, 10.0), (0.9, 2.4)),
    window(2, (11.8, 12.0), (12.0, 14.0), (0.9, 2.4)),
    // Dining room: south and west.
    window(2, (11.8, 12.0), (2.0, 4.0), (0.9, 2.4)),
    window(2, (11.8, 12.0), (6.0, 8.0), (0.9, 2.4)),
    window(0, (0.0, 0.2), (9.2, 10.8), (0.9, 2.4)),
];

/// The materials: linear RGB albedos, all components well below 1.
struct Mats {
    plaster: u32,
    paint_blue: u32,
    paint_sage: u32,
    render: u32,
    ceiling: u32,
    oak: u32,
    stone_floor: u32,
    tile: u32,
    stone: u32,
    walnut: u32,
    pine: u32,
    fabric_red: u32,
    fabric_blue: u32,
    linen: u32,
    metal: u32,
    rug: u32,
    books: [u32; 4],
    lamp: u32,
}

impl Mats {
    fn new(b: &mut MeshBuilder) -> Mats {
        let z = [0.0; 3];
        Mats {
            plaster: b.material("plaster", [0.80, 0.78, 0.74], z),
            paint_blue: b.material("paint_blue", [0.55, 0.64, 0.74], z),
            paint_sage: b.material("paint_sage", [0.60, 0.68, 0.55], z),
            render: b.material("render", [0.62, 0.58, 0.52], z),
            ceiling: b.material("ceiling", [0.86, 0.86, 0.84], z),
            oak: b.material("oak", [0.50, 0.35, 0.22], z),
            stone_floor: b.material("stone_floor", [0.62, 0.60, 0.56], z),
            tile: b.material("tile", [0.58, 0.50, 0.44], z),
            stone: b.material("stone", [0.72, 0.68, 0.60], z),
            walnut: b.material("walnut", [0.28, 0.18, 0.11], z),
            pine: b.material("pine", [0.62, 0.48, 0.30], z),
            fabric_red: b.material("fabric_red", [0.55, 0.12, 0.10], z),
            fabric_blue: b.material("fabric_blue", [0.16, 0.26, 0.50], z),
            linen: b.material("linen", [0.86, 0.84, 0.78], z),
            metal: b.material("metal", [0.35, 0.35, 0.37], z),
            rug: b.material("rug", [0.20, 0.38, 0.22], z),
            books: [
                b.material("book_red", [0.50, 0.10, 0.08], z),
                b.material("book_ochre", [0.70, 0.55, 0.18], z),
                b.material("book_teal", [0.10, 0.40, 0.42], z),
                b.material("book_cream", [0.80, 0.76, 0.64], z),
            ],
            lamp: b.material("lamp", [0.80, 0.80, 0.78], [12.0, 11.0, 9.0]),
        }
    }
}

/// A small deterministic generator (xorshift64*) for the books.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A value in `[lo, hi)` rounded to millimetres.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        ((lo + (hi - lo) * self.next()) * 1000.0).round() / 1000.0
    }
}

/// Where a piece of furniture looks: its local +z (its front) is turned to
/// face south (+z), east (+x), north (−z) or west (−x).
#[derive(Clone, Copy)]
enum Facing {
    S,
    E,
    N,
    W,
}

/// A local frame for furniture: a rotation about y by a multiple of 90
/// degrees and a translation, so local axis-aligned boxes stay
/// axis-aligned.
struct Frame {
    o: DVec3,
    rot: u8,
}

fn rotate(rot: u8, p: DVec3) -> DVec3 {
    match rot % 4 {
        0 => p,
        1 => DVec3::new(p.z, p.y, -p.x),
        2 => DVec3::new(-p.x, p.y, -p.z),
        _ => DVec3::new(-p.z, p.y, p.x),
    }
}

impl Frame {
    /// The frame that puts the local footprint `[0, w] × [0, d]` (at height
    /// `y0`) onto the world rectangle starting at `(x0, z0)`, front towards
    /// `facing`. The world footprint is `w × d` (x × z) facing north or
    /// south and `d × w` facing east or west.
    fn fit(x0: f64, z0: f64, y0: f64, w: f64, d: f64, facing: Facing) -> Frame {
        let rot = match facing {
            Facing::S => 0,
            Facing::E => 1,
            Facing::N => 2,
            Facing::W => 3,
        };
        let corners = [(0.0, 0.0), (w, 0.0), (0.0, d), (w, d)]
            .map(|(x, z)| rotate(rot, DVec3::new(x, 0.0, z)));
        let mx = corners.iter().map(|c| c.x).fold(f64::INFINITY, f64::min);
        let mz = corners.iter().map(|c| c.z).fold(f64::INFINITY, f64::min);
        Frame {
            o: DVec3::new(x0 - mx, y0, z0 - mz),
            rot,
        }
    }

    fn map(&self, p: DVec3) -> DVec3 {
        self.o + rotate(self.rot, p)
    }
}

/// The builder with the scene's materials, the books' generator and the
/// floor areas covered by furniture (cut out of the floors).
struct Interior {
    b: MeshBuilder,
    m: Mats,
    rng: Rng,
    floor_cuts: Vec<[f64; 4]>,
}

/// Holes of the wall face in the plane `p[axis] = at`, from `OPENINGS`.
fn opening_holes(axis: usize, at: f64) -> Vec<[f64; 4]> {
    OPENINGS
        .iter()
        .filter(|o| o.axis == axis && ((o.t.0 - at).abs() < 1e-9 || (o.t.1 - at).abs() < 1e-9))
        .map(|o| [o.a.0, o.a.1, o.y.0, o.y.1])
        .collect()
}

fn inside(h: &[f64; 4], a: f64, b: f64) -> bool {
    a > h[0] && a < h[1] && b > h[2] && b < h[3]
}

impl Interior {
    fn mat(&mut self, m: u32) {
        self.b.set_material(m);
    }

    /// A planar face perpendicular to `axis` at `at` facing `sign`, over
    /// `a × b` (local coordinates of `plane_axes`), minus the openings in
    /// that plane, minus `holes`, and restricted to where `region` holds.
    #[allow(clippy::too_many_arguments)]
    fn face(
        &mut self,
        axis: usize,
        at: f64,
        sign: f64,
        a: (f64, f64),
        b: (f64, f64),
        holes: &[[f64; 4]],
        region_cuts: (&[f64], &[f64]),
        region: &dyn Fn(f64, f64) -> bool,
    ) {
        let mut all = if axis == 1 {
            Vec::new()
        } else {
            opening_holes(axis, at)
        };
        all.extend_from_slice(holes);
        let mut cuts_a: Vec<f64> = all.iter().flat_map(|h| [h[0], h[1]]).collect();
        let mut cuts_b: Vec<f64> = all.iter().flat_map(|h| [h[2], h[3]]).collect();
        cuts_a.extend_from_slice(region_cuts.0);
        cuts_b.extend_from_slice(region_cuts.1);
        let keep = |x: f64, y: f64| region(x, y) && !all.iter().any(|h| inside(h, x, y));
        self.b
            .plane_region(axis, at, sign, a, b, &cuts_a, &cuts_b, &keep);
    }

    /// A wall face (or floor, ceiling) with openings and extra holes.
    fn wall(
        &mut self,
        axis: usize,
        at: f64,
        sign: f64,
        a: (f64, f64),
        b: (f64, f64),
        holes: &[[f64; 4]],
    ) {
        self.face(axis, at, sign, a, b, holes, (&[], &[]), &|_, _| true);
    }

    /// A room: its floor (minus `floor_cuts`), its ceiling (minus
    /// `ceiling_cuts`) and its four inner wall faces, each minus the
    /// openings in its plane and the given extra holes (`[west, east,
    /// north, south]`), all facing into the room.
    #[allow(clippy::too_many_arguments)]
    fn room(
        &mut self,
        x: (f64, f64),
        z: (f64, f64),
        h: f64,
        walls: u32,
        floor: u32,
        extra: [&[[f64; 4]]; 4],
        floor_cuts: &[[f64; 4]],
        ceiling_cuts: &[[f64; 4]],
    ) {
        self.mat(walls);
        self.wall(0, x.0, 1.0, z, (0.0, h), extra[0]);
        self.wall(0, x.1, -1.0, z, (0.0, h), extra[1]);
        self.wall(2, z.0, 1.0, x, (0.0, h), extra[2]);
        self.wall(2, z.1, -1.0, x, (0.0, h), extra[3]);
        self.mat(floor);
        self.wall(1, 0.0, 1.0, x, z, floor_cuts);
        let ceiling = self.m.ceiling;
        self.mat(ceiling);
        self.wall(1, h, -1.0, x, z, ceiling_cuts);
    }

    /// The reveals of every opening: jambs, sill (the threshold of a door)
    /// and head, spanning the wall's thickness and facing into the opening.
    fn reveals(&mut self) {
        let plaster = self.m.plaster;
        self.mat(plaster);
        for o in OPENINGS {
            if o.axis == 0 {
                // Wall across x; the opening runs along z.
                self.b.plane_rect(2, o.a.0, 1.0, o.t, o.y);
                self.b.plane_rect(2, o.a.1, -1.0, o.t, o.y);
                self.b.plane_rect(1, o.y.0, 1.0, o.t, o.a);
                self.b.plane_rect(1, o.y.1, -1.0, o.t, o.a);
            } else {
                // Wall across z; the opening runs along x.
                self.b.plane_rect(0, o.a.0, 1.0, o.t, o.y);
                self.b.plane_rect(0, o.a.1, -1.0, o.t, o.y);
                self.b.plane_rect(1, o.y.0, 1.0, o.a, o.t);
                self.b.plane_rect(1, o.y.1, -1.0, o.a, o.t);
            }
        }
    }

    /// The exterior faces of the outer walls: the hall block rises to 7.2 m
    /// (x < 10.1, z < 8.1), the rest to 3.7 m.
    fn exterior(&mut self) {
        let render = self.m.render;
        self.mat(render);
        let hall_x = 10.1;
        let hall_z = 8.1;
        // North (z = 0) and west (x = 0): tall over the hall block.
        self.face(
            2,
            0.0,
            -1.0,
            (0.0, 18.0),
            (0.0, HALL_TOP),
            &[],
            (&[hall_x], &[WING_TOP]),
            &|x, y| x < hall_x || y < WING_TOP,
        );
        self.face(
            0,
            0.0,
            -1.0,
            (0.0, 12.0),
            (0.0, HALL_TOP),
            &[],
            (&[hall_z], &[WING_TOP]),
            &|z, y| z < hall_z || y < WING_TOP,
        );
        self.wall(0, 18.0, 1.0, (0.0, 12.0), (0.0, WING_TOP), &[]);
        self.wall(2, 12.0, 1.0, (0.0, 18.0), (0.0, WING_TOP), &[]);
        // The hall block's walls above the lower roofs.
        self.wall(0, hall_x, 1.0, (0.0, hall_z), (WING_TOP, HALL_TOP), &[]);
        self.wall(2, hall_z, 1.0, (0.0, hall_x), (WING_TOP, HALL_TOP), &[]);
        // The roofs close the shell, so the building occludes the sun in a
        // shadow map whichever faces it culls. Nothing inside sees them, so
        // they use 0.5 m cells.
        let cell = self.b.max_cell;
        self.b.max_cell = ROOF_CELL;
        self.wall(1, HALL_TOP, 1.0, (0.0, hall_x), (0.0, hall_z), &[]);
        self.face(
            1,
            WING_TOP,
            1.0,
            (0.0, 18.0),
            (0.0, 12.0),
            &[],
            (&[hall_x], &[hall_z]),
            &|x, z| x > hall_x || z > hall_z,
        );
        self.b.max_cell = cell;
    }

    /// An axis-aligned box given in a furniture frame (local corners `lo`,
    /// `hi`, local face mask).
    fn fbox(&mut self, f: &Frame, lo: [f64; 3], hi: [f64; 3], mask: u8) {
        let a = f.map(DVec3::from_array(lo));
        let c = f.map(DVec3::from_array(hi));
        let (wlo, whi) = (a.min(c), a.max(c));
        let inverse = (4 - f.rot) % 4;
        let mut world = 0u8;
        for axis in 0..3 {
            for (k, s) in [(0, -1.0), (1, 1.0)] {
                let mut d = DVec3::ZERO;
                d[axis] = s;
                let l = rotate(inverse, d);
                let (la, ls) = (0..3)
                    .map(|i| (i, l[i]))
                    .find(|&(_, v)| v.abs() > 0.5)
                    .unwrap();
                let bit = 2 * la + usize::from(ls > 0.0);
                if mask & (1 << bit) != 0 {
                    world |= 1 << (2 * axis + k);
                }
            }
        }
        self.b.axis_box(wlo, whi, world);
    }

    /// Records the world footprint of local `[x0, x1] × [z0, z1]` as covered
    /// floor.
    fn cover_floor(&mut self, f: &Frame, x: (f64, f64), z: (f64, f64)) {
        let a = f.map(DVec3::new(x.0, 0.0, z.0));
        let c = f.map(DVec3::new(x.1, 0.0, z.1));
        self.floor_cuts
            .push([a.x.min(c.x), a.x.max(c.x), a.z.min(c.z), a.z.max(c.z)]);
    }

    /// A table `w × d`, `h` high: a 4 cm top on four 6 cm legs.
    fn table(&mut self, f: &Frame, w: f64, d: f64, h: f64, mat: u32) {
        self.mat(mat);
        self.fbox(f, [0.0, h - 0.04, 0.0], [w, h, d], ALL);
        for (x, z) in [
            (0.04, 0.04),
            (w - 0.1, 0.04),
            (0.04, d - 0.1),
            (w - 0.1, d - 0.1),
        ] {
            self.fbox(
                f,
                [x, 0.0, z],
                [x + 0.06, h - 0.04, z + 0.06],
                NX | PX | NZ | PZ,
            );
        }
    }

    /// A chair 0.44 m square, seat at 0.46 m, backrest at its back (local
    /// z = 0): the sitter looks towards local +z.
    fn chair(&mut self, f: &Frame, wood: u32, seat: u32) {
        self.mat(wood);
        for (x, z) in [(0.0, 0.0), (0.405, 0.0), (0.0, 0.405), (0.405, 0.405)] {
            self.fbox(
                f,
                [x, 0.0, z],
                [x + 0.035, 0.42, z + 0.035],
                NX | PX | NZ | PZ,
            );
        }
        self.fbox(f, [0.0, 0.92, 0.0], [0.44, 0.96, 0.035], ALL);
        for x in [0.0, 0.405] {
            self.fbox(
                f,
                [x, 0.46, 0.0],
                [x + 0.035, 0.92, 0.035],
                NX | PX | NZ | PZ,
            );
        }
        self.mat(seat);
        self.fbox(f, [0.0, 0.42, 0.0], [0.44, 0.46, 0.44], ALL);
    }

    /// A sofa `w` wide and 0.9 m deep with arms, seat and back cushions;
    /// its back is at local z = 0.
    fn sofa(&mut self, f: &Frame, w: f64, fabric: u32) {
        self.mat(fabric);
        self.fbox(f, [0.0, 0.0, 0.0], [w, 0.40, 0.9], ALL & !NY);
        self.fbox(f, [0.0, 0.40, 0.0], [w, 0.85, 0.2], ALL & !NY);
        self.fbox(f, [0.0, 0.40, 0.2], [0.18, 0.62, 0.9], ALL & !NY & !NZ);
        self.fbox(f, [w - 0.18, 0.40, 0.2], [w, 0.62, 0.9], ALL & !NY & !NZ);
        let inner = w - 0.36;
        let n = ((inner / 0.65).round() as usize).max(1);
        let cw = inner / n as f64;
        for i in 0..n {
            let x0 = 0.18 + cw * i as f64 + 0.01;
            let x1 = 0.18 + cw * (i + 1) as f64 - 0.01;
            self.fbox(f, [x0, 0.40, 0.2], [x1, 0.50, 0.88], ALL & !NY);
            self.fbox(f, [x0, 0.50, 0.2], [x1, 0.80, 0.36], ALL & !NY & !NZ);
        }
        self.cover_floor(f, (0.0, w), (0.0, 0.9));
    }

    /// A bookcase `w` wide, `h` high, `d` deep with `shelves` compartments
    /// filled with books of random sizes and colours (deterministic); its
    /// back (local z = 0) stands against a wall.
    fn bookcase(&mut self, f: &Frame, w: f64, h: f64, d: f64, shelves: usize) {
        let wood = self.m.walnut;
        self.mat(wood);
        self.fbox(f, [0.0, 0.0, 0.0], [0.02, h, d], ALL & !NY & !NZ);
        self.fbox(f, [w - 0.02, 0.0, 0.0], [w, h, d], ALL & !NY & !NZ);
        self.fbox(f, [0.02, h - 0.02, 0.0], [w - 0.02, h, d], PY | NY | PZ);
        self.fbox(f, [0.02, 0.0, 0.01], [w - 0.02, 0.08, d], PY | PZ);
        self.fbox(f, [0.02, 0.08, 0.0], [w - 0.02, h - 0.02, 0.01], PZ);
        let pitch = (h - 0.1) / shelves as f64;
        let mut bottoms = vec![0.08];
        for k in 1..shelves {
            let y = 0.08 + pitch * k as f64;
            self.fbox(f, [0.02, y, 0.01], [w - 0.02, y + 0.02, d], PY | NY | PZ);
            bottoms.push(y + 0.02);
        }
        for (k, &y0) in bottoms.iter().enumerate() {
            let y1 = if k + 1 < shelves {
                0.08 + pitch * (k + 1) as f64
            } else {
                h - 0.02
            };
            let max_h = (y1 - y0 - 0.03).min(0.32);
            let mut x = 0.03;
            loop {
                if self.rng.next() < 0.1 {
                    x += self.rng.range(0.03, 0.12);
                    continue;
                }
                let bw = self.rng.range(0.018, 0.05);
                if x + bw > w - 0.03 {
                    break;
                }
                let bh = self.rng.range(0.6 * max_h, max_h);
                let bd = self.rng.range(0.6 * (d - 0.03), d - 0.03);
                let mat = self.m.books[(self.rng.next() * 4.0) as usize % 4];
                self.mat(mat);
                self.fbox(
                    f,
                    [x, y0, 0.01],
                    [x + bw, y0 + bh, 0.01 + bd],
                    NX | PX | PY | PZ,
                );
                x += bw + 0.002;
            }
            self.mat(wood);
        }
        self.cover_floor(f, (0.0, w), (0.0, d));
    }

    /// A cabinet `w × d × h` on short legs with `doors` door panels on its
    /// front; its back (local z = 0) stands against a wall.
    #[allow(clippy::too_many_arguments)]
    fn cabinet(&mut self, f: &Frame, w: f64, d: f64, h: f64, doors: usize, body: u32, front: u32) {
        self.mat(body);
        let legs = h > 1.0;
        let y0 = if legs { 0.0 } else { 0.1 };
        let mask = if legs { ALL & !NY & !NZ } else { ALL & !NZ };
        self.fbox(f, [0.0, y0, 0.0], [w, h, d], mask);
        if !legs {
            for (x, z) in [
                (0.03, 0.03),
                (w - 0.07, 0.03),
                (0.03, d - 0.07),
                (w - 0.07, d - 0.07),
            ] {
                self.fbox(f, [x, 0.0, z], [x + 0.04, 0.1, z + 0.04], NX | PX | NZ | PZ);
            }
        } else {
            self.cover_floor(f, (0.0, w), (0.0, d));
        }
        self.mat(front);
        let dw = w / doors as f64;
        for i in 0..doors {
            let x0 = dw * i as f64 + 0.01;
            self.fbox(
                f,
                [x0, y0 + 0.04, d],
                [x0 + dw - 0.02, h - 0.04, d + 0.015],
                ALL & !NZ,
            );
        }
    }

    /// A double bed 1.6 × 2.05 m: headboard at local z = 0, frame,
    /// mattress, two pillows and a duvet over the foot end.
    fn bed(&mut self, f: &Frame) {
        let (w, l) = (1.6, 2.05);
        let (walnut, linen, blue) = (self.m.walnut, self.m.linen, self.m.fabric_blue);
        self.mat(walnut);
        self.fbox(f, [0.0, 0.0, 0.0], [w, 1.1, 0.08], ALL & !NY & !NZ);
        self.fbox(f, [0.0, 0.0, 0.08], [w, 0.35, l], ALL & !NY & !NZ);
        self.mat(linen);
        self.fbox(f, [0.03, 0.35, 0.1], [w - 0.03, 0.58, 0.7], ALL & !NY & !PZ);
        self.fbox(f, [0.12, 0.58, 0.15], [0.74, 0.70, 0.55], ALL & !NY);
        self.fbox(f, [w - 0.74, 0.58, 0.15], [w - 0.12, 0.70, 0.55], ALL & !NY);
        self.mat(blue);
        self.fbox(f, [0.0, 0.35, 0.7], [w, 0.63, l], ALL & !NY);
        self.cover_floor(f, (0.0, w), (0.0, l));
    }

    /// A nightstand with a drawer front; back at local z = 0.
    fn nightstand(&mut self, f: &Frame) {
        let (walnut, pine) = (self.m.walnut, self.m.pine);
        self.cabinet(f, 0.45, 0.4, 0.5, 1, walnut, pine);
    }

    /// A rug: a 12 mm slab on the floor.
    fn rug(&mut self, x: (f64, f64), z: (f64, f64)) {
        let m = self.m.rug;
        self.mat(m);
        self.b.axis_box(
            DVec3::new(x.0, 0.0, z.0),
            DVec3::new(x.1, 0.012, z.1),
            ALL & !NY,
        );
        self.floor_cuts.push([x.0, x.1, z.0, z.1]);
    }

    /// A round pedestal table of radius `r` standing on height `y0`.
    fn round_table(&mut self, cx: f64, cz: f64, y0: f64, r: f64, h: f64) {
        let m = self.m.walnut;
        self.mat(m);
        self.b
            .cylinder(DVec3::new(cx, y0 + h - 0.04, cz), r, 0.04, 40, (true, true));
        self.b.cylinder(
            DVec3::new(cx, y0 + 0.03, cz),
            0.05,
            h - 0.07,
            12,
            (false, false),
        );
        self.b
            .cylinder(DVec3::new(cx, y0, cz), 0.25, 0.03, 24, (false, true));
    }

    /// A square ceiling lamp 0.6 m wide, 8 cm deep: metal sides and an
    /// emissive bottom face. Returns the ceiling area it covers.
    fn lamp(&mut self, cx: f64, cz: f64, h: f64) -> [f64; 4] {
        let (metal, lamp) = (self.m.metal, self.m.lamp);
        let r = [cx - 0.3, cx + 0.3, cz - 0.3, cz + 0.3];
        self.mat(metal);
        self.b.axis_box(
            DVec3::new(r[0], h - 0.08, r[2]),
            DVec3::new(r[1], h, r[3]),
            NX | PX | NZ | PZ,
        );
        self.mat(lamp);
        self.b
            .plane_rect(1, h - 0.08, -1.0, (r[0], r[1]), (r[2], r[3]));
        r
    }

    /// Takes the floor cuts recorded so far.
    fn take_cuts(&mut self) -> Vec<[f64; 4]> {
        std::mem::take(&mut self.floor_cuts)
    }
}

fn normalized(v: [f64; 3]) -> [f32; 3] {
    let d = DVec3::from_array(v).normalize();
    [d.x as f32, d.y as f32, d.z as f32]
}

pub(super) fn build() -> Result<GeneratedScene, usize> {
    let mut b = MeshBuilder::new(DECIMALS, MAX_CELL);
    let m = Mats::new(&mut b);
    let mut s = Interior {
        b,
        m,
        rng: Rng(0x9E37_79B9_7F4A_7C15),
        floor_cuts: Vec::new(),
    };
    hall(&mut s);
    living(&mut s);
    bedroom(&mut s);
    dining(&mut s);
    s.reveals();
    s.exterior();

    let config = SceneConfig {
        sky: None,
        objects: Vec::new(),
        emission: Default::default(),
        camera: Camera {
            position: [9.0, 1.7, 7.3],
            target: [3.0, 2.8, 2.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
        },
        lights: vec![
            Light::Directional {
                direction: normalized([0.5, -0.55, -0.67]),
                irradiance: [6.0, 5.7, 5.2],
            },
            Light::Spot {
                position: [6.2, 6.9, 5.2],
                direction: [0.0, -1.0, 0.0],
                intensity: [40.0, 38.0, 34.0],
                cone_angle_deg: 30.0,
                beam_angle_deg: 20.0,
            },
            Light::Point {
                position: [13.6, 2.6, 9.0],
                intensity: [6.0, 5.5, 4.5],
            },
        ],
        units: "m".into(),
        description: "Architectural interior, metres: a 7 m hall with a mezzanine on an arcade \
            of four arches and three columns, reached by a 20-riser stair; a living room, a \
            bedroom and a dining room (3.5 m), 0.2 m walls modelled on both sides with door and \
            window reveals, furniture, two emissive ceiling lamps (material `lamp`, Ke 12 11 9, \
            in the living and dining rooms). Lights: a sun from the south-west entering the \
            west and south windows, a spot under the hall ceiling over the sofa group, and a \
            point light in the bedroom. The camera stands in the hall's south-east corner \
            looking at the arcade and the stair."
            .into(),
    };
    assemble(
        "interior",
        &[
            "Architectural interior: four rooms, a mezzanine on an arcade, a stair, furniture.",
            "Units: metres. Generated by `radiosity generate interior`; do not edit.",
        ],
        DECIMALS as usize,
        s.b,
        config,
    )
}

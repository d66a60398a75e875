//! Covered geometry (docs/design.md bake step 2; the voxelizer's module doc,
//! "Covered geometry"): the one rule for whether a point of a surface can
//! be seen at all. A point is covered when the first surface in front of it
//! along its normal is the back of another surface within
//! [`COVER_DISTANCE`] voxels, or any surface within [`COVER_GAP`] voxels, or
//! it is enclosed: every ray of a fixed fan around its normal meets a back
//! face first, at any distance, or it lies *on a surface inside a solid*:
//! a coincident triangle facing the other way is there, and from that
//! triangle's side the first surface is the back of another within the
//! cover distance, or it is enclosed (the bottom of a block standing on a
//! floor, where the floor is inside the block; left uncovered, such pieces
//! faced out under the floor, and joined each other there beneath a thin
//! wall, a leak). A two-sided surface modelled as two coincident triangles
//! is not: each face's other side sees the scene, or a thin gap.
//! A back face with a coincident front face is no back. The
//! voxelizer uses it for which pieces and how much of them a patch stands
//! for, the rays form factors for which ray origins a partly covered piece
//! casts from, the surface map for the patches' sample points.

use radiosity_core::bvh::Bvh;
use radiosity_core::math::{dot, tangent_basis};
use radiosity_core::patch::Grid;
use radiosity_core::scene::Scene;

/// Lift of a tested point off its surface along its normal, in voxel
/// sizes (as the voxelizer's connectivity segments: 8× the f32 rounding of
/// BVH coordinates relative to the grid centre), and the depth within
/// which a coincident front face cancels a back face.
pub const COVER_LIFT: f64 = 1e-3;

/// A piece's point is covered when the first surface in front of it along
/// its normal is the back of another surface within this many voxel sizes
/// (module doc, "Covered geometry").
pub const COVER_DISTANCE: f64 = 0.5;

/// Rays of the enclosure test (module doc, "Covered geometry"): along the
/// normal and a fan of `ENCLOSED_RAYS − 1` directions at
/// [`ENCLOSED_POLAR`] from it. A point whose every ray meets a back face
/// first is inside a closed solid; one ray that escapes or meets a front
/// face proves it is not, so open surfaces cost one or two rays a point.
pub const ENCLOSED_RAYS: usize = 8;

/// Polar angle of the enclosure test's fan, radians (60°: between the
/// normal and the horizon, so a box's walls and its top are both probed).
pub const ENCLOSED_POLAR: f64 = std::f64::consts::FRAC_PI_3;

/// Points tested per piece for covered geometry (module doc).
pub const COVER_POINTS: usize = 16;

/// Times the normal probe steps over the point's own triangle before it
/// gives up (a grazing start meets it at most once or twice).
const OWN_SKIPS: usize = 4;

/// A piece's point is covered when any other surface, front or back, lies
/// within this many voxel sizes in front of it (module doc).
pub const COVER_GAP: f64 = 0.05;

/// The covered-point rule (module doc, "Covered geometry"), shared by the
/// voxelizer (which pieces and how much of them a patch stands for) and the
/// rays form factors (which ray origins stand for a partly covered piece).
pub struct Cover<'a> {
    bvh: &'a Bvh,
    normals: &'a [[f64; 3]],
    shift: [f64; 3],
    lift: f64,
    cover: f64,
    gap: f64,
    reach: f64,
}

impl<'a> Cover<'a> {
    /// The rule at `grid`'s voxel size over `bvh` (built with the shift
    /// `grid.centre()`), `normals` the scene's unit triangle normals.
    pub fn new(scene: &Scene, grid: &Grid, bvh: &'a Bvh, normals: &'a [[f64; 3]]) -> Cover<'a> {
        let (lo, hi) = scene.bounds();
        let diagonal = (0..3)
            .map(|q| (hi[q] - lo[q]) as f64)
            .map(|e| e * e)
            .sum::<f64>()
            .sqrt();
        Cover {
            bvh,
            normals,
            shift: grid.centre(),
            lift: COVER_LIFT * grid.size,
            cover: COVER_DISTANCE * grid.size,
            gap: COVER_GAP * grid.size,
            reach: 2.0 * diagonal + grid.size,
        }
    }

    /// Whether the point `x` (world) of triangle `tri`, unit normal `n`, is
    /// covered: the first surface in front is the back of a surface within
    /// [`COVER_DISTANCE`] voxels, or any surface within [`COVER_GAP`], or
    /// the point is enclosed.
    pub fn covered(&self, x: [f64; 3], n: [f64; 3], tri: u32) -> bool {
        let o: [f64; 3] = std::array::from_fn(|q| x[q] + self.lift * n[q] - self.shift[q]);
        self.first_surface_covers(o, n, tri)
            || self.enclosed(o, n, tri)
            || self.on_a_surface_inside_a_solid(o, n, tri)
    }

    /// A triangle facing the other way lies on the point (it crosses the
    /// normal within the lift on either side; `o` is the lifted point,
    /// shifted), and that surface is inside a solid there: from its side,
    /// the first surface is the back of another within the cover distance,
    /// or it is enclosed (module doc). A block's bottom on a floor is such
    /// a point (the floor under the block is inside the block); a two-sided
    /// panel's face is not (its other face sees the scene, or a thin gap).
    fn on_a_surface_inside_a_solid(&self, o: [f64; 3], n: [f64; 3], tri: u32) -> bool {
        let (bvh, normals) = (self.bvh, self.normals);
        let below: [f64; 3] = std::array::from_fn(|q| o[q] - 2.0 * self.lift * n[q]);
        let Some(k) = bvh.any_hit(below, n.map(|v| v * 2.0 * self.lift), |k, _| {
            let hit = bvh.order[k as usize];
            hit == tri || dot(normals[hit as usize], n) > -0.5
        }) else {
            return false;
        };
        let other = bvh.order[k as usize];
        let m = normals[other as usize];
        // The other surface's point, lifted off it on its side.
        let p: [f64; 3] = std::array::from_fn(|q| o[q] - self.lift * n[q] + self.lift * m[q]);
        self.first_surface_is_a_back(p, m, other) || self.enclosed(p, m, other)
    }

    /// The first surface along the normal from `o` (shifted) decides: its
    /// back within the cover distance covers, a front face (or a back with
    /// a coincident front) only within the gap. A back face behind a front
    /// face does not: the point faces open space up to that front face (a
    /// floor under a slab whose top lies within half a voxel; counting it,
    /// at 9 m voxels 7 % of Sponza's form-factor rays met pieces dropped
    /// that way and their light was lost). The point's own triangle, met at
    /// a grazing start, is stepped over.
    fn first_surface_covers(&self, o: [f64; 3], n: [f64; 3], tri: u32) -> bool {
        self.first_surface(o, n, tri)
            .is_some_and(|(back, d)| back || d <= self.gap)
    }

    /// [`Cover::first_surface_covers`] without the gap: the first surface
    /// is the back of another within the cover distance.
    fn first_surface_is_a_back(&self, o: [f64; 3], n: [f64; 3], tri: u32) -> bool {
        self.first_surface(o, n, tri).is_some_and(|(back, _)| back)
    }

    /// The first surface along the normal from `o` (shifted) within the
    /// cover distance, stepping over `tri`: whether it is a back (without a
    /// coincident front), and its distance.
    fn first_surface(&self, o: [f64; 3], n: [f64; 3], tri: u32) -> Option<(bool, f64)> {
        let (bvh, normals) = (self.bvh, self.normals);
        let mut start = 0.0f64;
        for _ in 0..OWN_SKIPS {
            let len = self.cover - start;
            if len <= 0.0 {
                return None;
            }
            let from: [f64; 3] = std::array::from_fn(|q| o[q] + start * n[q]);
            let (leaf, t) = bvh.closest_hit(from, n.map(|v| v * len))?;
            let d = start + t * len;
            let hit = bvh.order[leaf as usize];
            if hit == tri {
                start = d + 1e-9 * self.cover;
                continue;
            }
            let back = dot(normals[hit as usize], n) > 0.0 && self.front_at(o, n, d, tri).is_none();
            return Some((back, d));
        }
        None
    }

    /// A surface facing back along the unit direction `d` from `o`
    /// (shifted) that crosses it within `lift` of the distance `t` (its BVH
    /// leaf index; `tri` is ignored): the other side of a two-sided surface
    /// modelled as two coincident triangles, which makes the back face found
    /// there no back at all. The rays form factors credit such a hit to the
    /// front face.
    pub fn front_at(&self, o: [f64; 3], d: [f64; 3], t: f64, tri: u32) -> Option<u32> {
        let (bvh, normals) = (self.bvh, self.normals);
        let e = self.lift;
        let start: [f64; 3] = std::array::from_fn(|q| o[q] + (t - e) * d[q]);
        bvh.any_hit(start, d.map(|v| v * 2.0 * e), |k, _| {
            let hit = bvh.order[k as usize];
            hit == tri || dot(normals[hit as usize], d) >= 0.0
        })
    }

    /// Every direction of a fixed fan around the normal meets the back of a
    /// surface first: the point (`o`, shifted) is inside a closed solid (the
    /// floor under a box without a bottom face), at any distance.
    fn enclosed(&self, o: [f64; 3], n: [f64; 3], tri: u32) -> bool {
        (0..ENCLOSED_RAYS).all(|k| {
            let d = fan_direction(n, k, ENCLOSED_RAYS);
            self.bvh
                .closest_hit(o, d.map(|v| v * self.reach))
                .is_some_and(|(leaf, t)| {
                    let hit = self.bvh.order[leaf as usize];
                    hit != tri
                        && dot(self.normals[hit as usize], d) > 0.0
                        && self.front_at(o, d, t * self.reach, tri).is_none()
                })
        })
    }
}

/// Direction `k` of the enclosure test's fan of `rays` around the unit
/// vector `n`: `n` itself for `k = 0`, else evenly spaced in azimuth at
/// [`ENCLOSED_POLAR`] from `n` (also the facing check's back-side probe,
/// `bake::facing`).
pub fn fan_direction(n: [f64; 3], k: usize, rays: usize) -> [f64; 3] {
    if k == 0 {
        return n;
    }
    let (t, b) = tangent_basis(n);
    let (st, ct) = ENCLOSED_POLAR.sin_cos();
    let phi = std::f64::consts::TAU * (k - 1) as f64 / (rays - 1) as f64;
    std::array::from_fn(|q| st * (phi.cos() * t[q] + phi.sin() * b[q]) + ct * n[q])
}

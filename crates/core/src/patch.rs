//! Patches, the unit both phases share (docs/design.md section 2): a patch is
//! the simplified surface of one voxel facing one of the six axis
//! [`Direction`]s, with a centre, a unit normal, an area, an albedo and an
//! emission. [`Grid`] is the voxel grid the patches come from, and
//! [`Patch::frame`] the one definition of a patch's shape and tangent frame
//! — the square of its area in its plane, with edges along the grid axes
//! projected into that plane — that form factors, direct light, the preview
//! and the shaders use.

use crate::error::GridError;
use crate::math::{cross, dot, scale, sub, unit};
use serde::Serialize;

/// Most voxels along one axis: beyond 4096, f32 grid coordinates carry
/// rounding errors above the voxelizer's overlap-test margin
/// (`bake::voxelize::SAT_HALF`).
pub const MAX_DIM: u32 = 4096;

/// One of the six axis directions a patch can face.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Direction {
    PosX = 0,
    NegX = 1,
    PosY = 2,
    NegY = 3,
    PosZ = 4,
    NegZ = 5,
}

impl Direction {
    pub const ALL: [Direction; 6] = [
        Direction::PosX,
        Direction::NegX,
        Direction::PosY,
        Direction::NegY,
        Direction::PosZ,
        Direction::NegZ,
    ];

    /// The axis (0 = x, 1 = y, 2 = z).
    pub fn axis(self) -> usize {
        self as usize / 2
    }

    /// +1 or −1.
    pub fn sign(self) -> i64 {
        if (self as usize).is_multiple_of(2) {
            1
        } else {
            -1
        }
    }

    /// The unit vector.
    pub fn vector(self) -> [f64; 3] {
        let mut v = [0.0; 3];
        v[self.axis()] = self.sign() as f64;
        v
    }

    /// The signed axis of the largest component of `n` (ties go to the lower
    /// axis, so the choice is deterministic).
    pub fn dominant(n: [f64; 3]) -> Direction {
        let a = n.map(f64::abs);
        let axis = if a[0] >= a[1] && a[0] >= a[2] {
            0
        } else if a[1] >= a[2] {
            1
        } else {
            2
        };
        Direction::ALL[2 * axis + usize::from(n[axis] < 0.0)]
    }

    /// The direction facing the other way.
    pub fn opposite(self) -> Direction {
        Direction::ALL[self as usize ^ 1]
    }

    pub fn name(self) -> &'static str {
        ["+x", "-x", "+y", "-y", "+z", "-z"][self as usize]
    }
}

/// The voxel grid: boundaries at integer multiples of `size` in world space,
/// with one empty layer of padding around the scene's bounds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Grid {
    /// World position of voxel (0, 0, 0)'s minimum corner.
    pub origin: [f64; 3],
    /// Edge length of a voxel (scene units).
    pub size: f64,
    /// Voxels along each axis.
    pub dims: [u32; 3],
}

impl Grid {
    /// The grid of voxel size `size` covering `bounds`.
    pub fn new(bounds: ([f32; 3], [f32; 3]), size: f64) -> Result<Grid, GridError> {
        if !(size.is_finite() && size > 0.0) {
            return Err(GridError::VoxelSize(size));
        }
        let mut origin = [0.0; 3];
        let mut dims = [0u32; 3];
        for a in 0..3 {
            let lo = (bounds.0[a] as f64 / size).floor() - 1.0;
            let hi = (bounds.1[a] as f64 / size).floor() + 1.0;
            let n = hi - lo + 1.0;
            if n > MAX_DIM as f64 {
                return Err(GridError::TooFine {
                    size,
                    voxels: n,
                    axis: ['x', 'y', 'z'][a],
                    max: MAX_DIM,
                });
            }
            origin[a] = lo * size;
            dims[a] = n as u32;
        }
        Ok(Grid { origin, size, dims })
    }

    /// Grid coordinates of a world point (voxel (i, j, k) spans [i, i + 1]…).
    /// Computed as `p / size − lo` so that points on a voxel boundary at an
    /// exact multiple of a power-of-two size map to exact integers.
    pub fn to_grid(&self, p: [f32; 3]) -> [f64; 3] {
        std::array::from_fn(|a| p[a] as f64 / self.size - self.origin[a] / self.size)
    }

    /// The grid's centre: coordinates relative to it have the smallest f32
    /// rounding error (the BVH's shift point).
    pub fn centre(&self) -> [f64; 3] {
        std::array::from_fn(|k| self.origin[k] + 0.5 * self.size * self.dims[k] as f64)
    }

    /// Linear key of a voxel.
    pub fn key(&self, v: [u32; 3]) -> u64 {
        v[0] as u64 + self.dims[0] as u64 * (v[1] as u64 + self.dims[1] as u64 * v[2] as u64)
    }

    /// The neighbour of `v` in direction `d`, if inside the grid.
    pub fn neighbour(&self, v: [u32; 3], d: Direction) -> Option<[u32; 3]> {
        let mut n = v;
        let a = d.axis();
        let c = v[a] as i64 + d.sign();
        if c < 0 || c >= self.dims[a] as i64 {
            return None;
        }
        n[a] = c as u32;
        Some(n)
    }
}

/// A patch: the simplified surface of one voxel facing one direction.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Patch {
    /// Centre `c_i` (world units), in the mean plane of its geometry.
    pub centre: [f64; 3],
    /// Unit normal `N_i` of the mean plane.
    pub normal: [f64; 3],
    /// Area `A_i`: the geometry's area projected onto the mean plane.
    pub area: f64,
    /// Linear RGB albedo `ρ_i`.
    pub albedo: [f64; 3],
    /// Emitted exitance `E_i`.
    pub emission: [f64; 3],
    /// The voxel the patch came from.
    pub voxel: [u32; 3],
    pub direction: Direction,
}

/// A patch's square in its plane (module doc): in-plane unit axes `u`, `v`
/// with `u × v = n`, and the half side `√A / 2`. World coordinates, f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchFrame {
    pub u: [f64; 3],
    pub v: [f64; 3],
    pub n: [f64; 3],
    pub half: f64,
}

/// The four corners of a patch square in units of the half side, in the
/// order the form-factor kernel uses: (−u −v), (−u +v), (+u +v), (+u −v).
pub const CORNERS: [(f64, f64); 4] = [(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)];

impl Patch {
    /// The patch's square (module doc). `u` is the grid axis after the
    /// patch's facing axis, made orthogonal to the normal; `v = n × u`. For
    /// a patch of a surface aligned with the grid this is exactly the voxel
    /// face scaled to the patch's area, so full patches of a grid-aligned
    /// plate tile it without gap or overlap. Deterministic, from the patch
    /// alone.
    pub fn frame(&self) -> PatchFrame {
        let n = unit(self.normal);
        let a = self.direction.axis();
        let mut u = [0.0; 3];
        for step in 1..3 {
            let mut t = [0.0; 3];
            t[(a + step) % 3] = 1.0;
            let cand = sub(t, scale(n, dot(t, n)));
            // The patch normal is dominated by axis a, so the next axis is
            // never (nearly) parallel to it; the loop is a guard.
            if dot(cand, cand) > 1e-12 {
                u = unit(cand);
                break;
            }
        }
        PatchFrame {
            u,
            v: cross(n, u),
            n,
            half: 0.5 * self.area.max(0.0).sqrt(),
        }
    }

    /// The point at square coordinates `(a, b) ∈ [−1, 1]²` (in half sides).
    pub fn point(&self, frame: &PatchFrame, a: f64, b: f64) -> [f64; 3] {
        std::array::from_fn(|k| self.centre[k] + frame.half * (a * frame.u[k] + b * frame.v[k]))
    }
}

/// Sutherland–Hodgman: the part of a convex polygon where `dist ≥ 0`;
/// `snap` adjusts each new vertex on the boundary (an axis clip sets that
/// coordinate to the bound exactly).
fn clip_by(
    src: &[[f64; 3]],
    dist: impl Fn(&[f64; 3]) -> f64,
    snap: impl Fn(&mut [f64; 3]),
) -> Vec<[f64; 3]> {
    let m = src.len();
    let mut out = Vec::with_capacity(m + 1);
    for i in 0..m {
        let p = (i + m - 1) % m;
        let (dc, dp) = (dist(&src[i]), dist(&src[p]));
        let (cin, pin) = (dc >= 0.0, dp >= 0.0);
        if cin != pin {
            let t = dp / (dp - dc);
            let mut q: [f64; 3] = std::array::from_fn(|j| src[p][j] + t * (src[i][j] - src[p][j]));
            snap(&mut q);
            out.push(q);
        }
        if cin {
            out.push(src[i]);
        }
    }
    out
}

/// Against `x_k ≥ −slack` or `x_k ≤ 1 + slack` (the voxelization kernel's
/// `clip_axis`, in f64, at slack 0).
fn clip_axis(src: &[[f64; 3]], k: usize, keep_high: bool, slack: f64) -> Vec<[f64; 3]> {
    let bound = if keep_high { 1.0 + slack } else { -slack };
    let dist = |p: &[f64; 3]| {
        if keep_high {
            bound - p[k]
        } else {
            p[k] - bound
        }
    };
    clip_by(src, dist, |q| q[k] = bound)
}

/// The part of a triangle (coordinates relative to a voxel's minimum
/// corner, in voxel units) inside the unit box: a convex polygon, empty
/// when they do not overlap.
pub fn clip_to_unit_box(v: [[f64; 3]; 3]) -> Vec<[f64; 3]> {
    clip_to_box(v, 0.0)
}

/// [`clip_to_unit_box`] with the box grown by `slack` (voxel units) on
/// every side.
fn clip_to_box(v: [[f64; 3]; 3], slack: f64) -> Vec<[f64; 3]> {
    let mut poly = v.to_vec();
    for k in 0..3 {
        if poly.is_empty() {
            break;
        }
        poly = clip_axis(&poly, k, false, slack);
        poly = clip_axis(&poly, k, true, slack);
    }
    poly
}

/// How far (voxel units) [`piece_polygon_local`] reaches past a voxel's
/// faces for a piece the exact clip leaves without area: the OpenCL
/// voxelizer places a surface lying in a voxel face by f32 grid
/// coordinates (their rounding is ~1e-4 voxels at a 1,000-voxel grid), and
/// where that rounding puts it in the other voxel than the host's f64, the
/// exact clip finds nothing (a box's side at x = 0.3 at voxel 0.1: every
/// patch of it had no surface to cast rays from, and the bake saw nothing).
pub const FACE_SLACK: f64 = 1e-3;

/// A plane cutting a triangle's piece in two where another surface (a
/// thin wall standing on a big floor triangle) crosses it inside its voxel
/// (the voxelizer's module doc, "Pieces cut by a wall"), in the voxel's
/// own coordinates (minimum corner 0, edge 1): `n · p = d`. f32, as the
/// bake file stores it, so the bake and the run time split at the same
/// place.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Cut {
    pub n: [f32; 3],
    pub d: f32,
}

impl Cut {
    /// Signed distance-like value of a voxel-local point: `≥ 0` on the
    /// positive side.
    pub fn side(&self, p: [f64; 3]) -> f64 {
        (0..3).map(|q| self.n[q] as f64 * p[q]).sum::<f64>() - self.d as f64
    }
}

/// The most cuts one piece takes (a wall thinner than a voxel has two
/// faces in it; a corner of two such walls, four planes, is cut by three).
pub const MAX_CUTS: usize = 3;

/// The part of a piece that a chain of cuts leaves (the voxelizer's
/// "Pieces cut by a wall"): on the given side of each cut in turn. A piece
/// cut `m` times becomes `m + 1` parts: part `i < m` is on the negative
/// side of cuts `0..i` and the positive side of cut `i`; the last part is
/// on the negative side of every cut. Empty for a whole piece.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Region {
    sides: [(Cut, bool); MAX_CUTS],
    len: u8,
}

impl Region {
    /// The cuts and sides (`true`: `n · p ≥ d`).
    pub fn sides(&self) -> &[(Cut, bool)] {
        &self.sides[..self.len as usize]
    }

    /// This region, also on `positive`'s side of `cut` (`None` past
    /// [`MAX_CUTS`]).
    pub fn with(&self, cut: Cut, positive: bool) -> Option<Region> {
        let mut r = *self;
        *r.sides.get_mut(r.len as usize)? = (cut, positive);
        r.len += 1;
        Some(r)
    }

    /// Whether a voxel-local point lies in the region (on the cut planes
    /// themselves: the positive side).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.sides()
            .iter()
            .all(|&(c, positive)| (c.side(p) >= 0.0) == positive)
    }

    /// The cut of a part that is followed by others in its chain: its last
    /// cut, when on the positive side.
    pub fn own_cut(&self) -> Option<Cut> {
        self.sides().last().filter(|s| s.1).map(|s| s.0)
    }

    /// The region shrunk by `inset` (voxel units) away from each of its
    /// cut planes.
    pub fn inset(&self, inset: f32) -> Region {
        let mut r = *self;
        for (c, positive) in &mut r.sides[..self.len as usize] {
            c.d += if *positive { inset } else { -inset };
        }
        r
    }

    /// Negative sides taken: the part's position in its chain.
    pub fn position(&self) -> usize {
        self.sides().iter().filter(|s| !s.1).count()
    }
}

/// Sutherland–Hodgman against one side of a [`Cut`].
pub fn clip_side(src: &[[f64; 3]], cut: Cut, positive: bool) -> Vec<[f64; 3]> {
    let sign = if positive { 1.0 } else { -1.0 };
    clip_by(src, |p| sign * cut.side(*p), |_| {})
}

/// A voxel-local polygon clipped to a [`Region`].
pub fn clip_region(poly: Vec<[f64; 3]>, region: &Region) -> Vec<[f64; 3]> {
    region.sides().iter().fold(poly, |p, &(c, positive)| {
        if p.is_empty() {
            p
        } else {
            clip_side(&p, c, positive)
        }
    })
}

/// The part of a triangle's piece in voxel `voxel` (voxel-local
/// coordinates, as [`clip_to_unit_box`]): the triangle inside the unit box,
/// and for a cut piece inside its region.
pub fn piece_polygon_local(coords: &[f64; 9], voxel: [u32; 3], region: &Region) -> Vec<[f64; 3]> {
    let local: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|q| coords[3 * i + q] - voxel[q] as f64));
    let mut poly = clip_to_unit_box(local);
    if !has_area(&poly) {
        // A surface in the voxel's face that the kernel placed on this
        // side ([`FACE_SLACK`]); its polygon then lies in that face.
        poly = clip_to_box(local, FACE_SLACK);
        for p in &mut poly {
            for c in p.iter_mut() {
                *c = c.clamp(0.0, 1.0);
            }
        }
    }
    clip_region(poly, region)
}

/// Whether a planar polygon has any area.
fn has_area(poly: &[[f64; 3]]) -> bool {
    (1..poly.len().saturating_sub(1)).any(|i| {
        let c = cross(sub(poly[i], poly[0]), sub(poly[i + 1], poly[0]));
        c.iter().any(|&x| x != 0.0)
    })
}

/// The world-space polygon of a triangle's piece in voxel `voxel`, from
/// the triangle's grid coordinates (`bake::voxelize::grid_coords`); for a
/// cut piece, its region.
pub fn piece_polygon(
    grid: &Grid,
    coords: &[f64; 9],
    voxel: [u32; 3],
    region: &Region,
) -> Vec<[f64; 3]> {
    piece_polygon_local(coords, voxel, region)
        .into_iter()
        .map(|p| std::array::from_fn(|q| grid.origin[q] + grid.size * (voxel[q] as f64 + p[q])))
        .collect()
}

/// How evenly a set of patches shares the area: the 10th, 50th and 90th
/// percentiles of patch area in voxel faces (`size²`), and the patches
/// below [`AreaSpread::SMALL`] voxel faces, counted and as a share of the
/// patch area. A budget spent on area has its median near 1 and few small
/// patches; one spent on fragments (issue 42) a median far below 1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct AreaSpread {
    pub p10: f64,
    pub p50: f64,
    pub p90: f64,
    pub small: u64,
    pub small_area_share: f64,
}

impl AreaSpread {
    /// Patches below this many voxel faces are counted as small (the
    /// voxelization's fragment bound).
    pub const SMALL: f64 = 0.25;

    /// The spread of `areas` (scene units²) at voxel edge `size`. Empty or
    /// zero-size input gives zeros.
    pub fn of(areas: impl IntoIterator<Item = f64>, size: f64) -> AreaSpread {
        let face = size * size;
        let mut a: Vec<f64> = areas.into_iter().collect();
        if a.is_empty() || !(face > 0.0) {
            return AreaSpread::default();
        }
        a.sort_by(f64::total_cmp);
        // Nearest rank (the smallest value with at least q of the set at or
        // below it).
        let q = |f: f64| a[((f * a.len() as f64).ceil() as usize).clamp(1, a.len()) - 1] / face;
        let total: f64 = a.iter().sum();
        let small: Vec<f64> = a
            .iter()
            .copied()
            .filter(|&x| x < Self::SMALL * face)
            .collect();
        AreaSpread {
            p10: q(0.1),
            p50: q(0.5),
            p90: q(0.9),
            small: small.len() as u64,
            // `+ 0.0`: an empty f64 sum is −0.
            small_area_share: if total > 0.0 {
                small.iter().sum::<f64>() / total + 0.0
            } else {
                0.0
            },
        }
    }
}

impl std::fmt::Display for AreaSpread {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "patch areas in voxel faces: p10 {:.3}, median {:.3}, p90 {:.3}; {} below {} ({:.2} % of the area)",
            self.p10,
            self.p50,
            self.p90,
            self.small,
            Self::SMALL,
            100.0 * self.small_area_share
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A face lying in a voxel face, placed by the OpenCL kernel's f32 on
    /// the side where the host's f64 puts it 4e-16 outside: the exact clip
    /// finds nothing, the piece's polygon is the face inside the voxel.
    #[test]
    fn a_face_in_a_voxel_face_keeps_its_polygon_on_either_side() {
        let x = 3.0 - 4e-16;
        let coords = [x, 0.0, 0.0, x, 2.0, 0.0, x, 0.0, 2.0];
        let whole = Region::default();
        assert!(clip_to_unit_box(std::array::from_fn(|i| {
            std::array::from_fn(|q| coords[3 * i + q] - [3.0, 0.0, 0.0][q])
        }))
        .is_empty());
        let poly = piece_polygon_local(&coords, [3, 0, 0], &whole);
        assert!(has_area(&poly), "{poly:?}");
        assert!(poly
            .iter()
            .all(|p| p[0] == 0.0 && p.iter().all(|&c| (0.0..=1.0).contains(&c))));
        // The same face in the other voxel, and any piece with area, are
        // the exact clip.
        let other = piece_polygon_local(&coords, [2, 0, 0], &whole);
        assert_eq!(
            other,
            clip_to_unit_box(std::array::from_fn(|i| {
                std::array::from_fn(|q| coords[3 * i + q] - [2.0, 0.0, 0.0][q])
            }))
        );
        assert!(has_area(&other));
    }
}

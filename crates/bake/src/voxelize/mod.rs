//! Voxel simplification: the scene's triangles become *patches*, one per
//! occupied voxel and axis direction whose neighbour voxel is empty, if the
//! voxel holds geometry facing that way (docs/design.md section 1, step 2).
//!
//! The work is split in two:
//! 1. *Pieces* (OpenCL kernel `crates/bake/kernels/voxelize.cl`, CPU reference
//!    [`cpu_pieces`] in f64): for each triangle, the voxels it overlaps (a
//!    conservative separating-axis test) and the part of the triangle inside
//!    each of them (exact polygon clipping): area and centroid.
//! 2. *Reduction* (host, shared by both paths, f64, deterministic order):
//!    pieces are grouped by voxel and by the facing direction of their
//!    triangle (the signed axis of the largest normal component). A group
//!    becomes a patch lying in the mean plane of its geometry: centre = the
//!    area-weighted centroid, normal = the normalised sum of area-weighted
//!    normals `Σ A_t n_t`, area = `|Σ A_t n_t|`, which is the geometry's
//!    area projected onto that plane. For a flat plate at any angle to the
//!    grid this is exactly its area, which the thesis's full-voxel-face
//!    patches did not keep. Albedo and emission are averaged with the same
//!    projected-area weights `A_t (n_t · m)`.
//!
//! **Neighbour rule.** A group facing direction `d` in voxel `v` whose
//! neighbour `v + d` is empty becomes a patch (the thesis's rule). With a
//! surface voxelization that rule alone loses a strip of every surface
//! along every edge where it meets another (the wall's voxel next to the
//! floor has the floor in its neighbour), 16 % of the Cornell box's area,
//! so the occupied neighbour is looked at more closely:
//! - it holds geometry facing `d` too: the surface continues there (a plate
//!   at an angle to the grid crosses voxel layers as a staircase), so the
//!   group is merged into the neighbour's, following `d` until a voxel whose
//!   neighbour is open; this keeps the plate's area;
//! - it holds geometry facing `−d`: a surface looks back at this one from
//!   less than two voxels away (a column, a wall's other side, a box on the
//!   floor); the group stays a patch, because it receives and reflects
//!   light (the thesis's rule dropped it, which left Sponza's column sides
//!   black), and is counted (`facing_back_groups`);
//! - it holds only geometry perpendicular to `d`: a corner; the neighbour
//!   does not hide the group, which becomes a patch.
//!
//! Staircase merges join only groups whose surfaces are connected (below):
//! a floor does not continue into the floor of the room above.
//!
//! **Connected surfaces.** The pieces of one voxel facing one way need not
//! be one surface: the two sides of a wall thinner than a voxel give two
//! floors in one voxel, stacked floors give two ceilings. Averaging them
//! makes one patch that gathers light from both rooms and leaks it into
//! the dark one. So a group is split into components: a piece joins the
//! component of each of its [`NEAREST`] nearest pieces that it is
//! *connected* to, that is, when the segment between their centroids,
//! lifted [`CONNECT_LIFT`] voxels off their surfaces, crosses no triangle
//! other than ones facing the same direction within [`CONNECT_OWN`] of an
//! end (their own surface curving across the chord)
//! ([`radiosity_core::bvh::Bvh::surface_segment_clear`]). Components smaller than
//! [`SMALL_COMPONENT`] voxel faces (relief: a moulding's step, a bit of
//! ornament) join the nearest component they reach over a lift of
//! [`RELIEF_LIFT`] voxels, so relief lower than that does not split a
//! surface while a wall does. Each component becomes a patch (counted,
//! `split_groups`).
//!
//! **Pieces cut by a wall** ([`crate::cut`]): before anything else,
//! a piece that a wall thinner than a voxel crosses (a big floor triangle
//! under it) is cut along the wall's plane into a chain of parts, each a
//! piece of its own from then on with its [`Region`]; counted
//! (`cut_pieces`).
//!
//! **Covered geometry.** A piece's point is covered when, along its normal,
//! the first surface is the *back* of another surface within
//! [`COVER_DISTANCE`] voxels (the point is inside a solid or behind a
//! one-sided surface: the floor under a box without a bottom face, the
//! ceiling above a one-sided light panel, faces buried in a wall; a back
//! face behind a front face does not count, since the point faces open
//! space up to that front face), or any surface lies within [`COVER_GAP`]
//! voxels (a gap too thin to pass light at this resolution: the top of a
//! two-sided panel 1 cm under the ceiling), or the point is enclosed: every
//! ray of a fixed fan ([`ENCLOSED_RAYS`]) meets the back of a surface first,
//! at any distance (the floor under a box without a bottom face, taller
//! than half a voxel: nothing sees it, and left in a patch it made the
//! visible floor beside the box dark). A covered piece can neither
//! receive nor send light, yet as part of a patch it would dilute the
//! patch's albedo and area. Front faces beyond the gap do not cover: they
//! face the point across open space (a gallery floor under its vault), and
//! dropping them (the first version, at half a voxel for any surface)
//! removed 3.5 % of Sponza's visible area at 7.6 m voxels. [`COVER_POINTS`]
//! points per piece, stratified by area (the R2 sequence in the fan
//! triangle at each area quantile), and its corners are tested, each pulled
//! 1 % towards the centroid; a wholly covered piece is dropped (it keeps no
//! patch), a partly covered one counts with its visible share of the area
//! (five points, the first version, made a big floor piece with one point
//! under a column lose a fifth of its area), is joined to its neighbours
//! through a visible point, and the later stages use only its visible
//! part: the rays form factors cast no ray from a covered origin, the
//! patch sample points skip covered points ([`Cover`] is the one rule).
//! Counted, and the covered area reported by direction.
//!
//! **Boundaries.** Voxel boundaries lie at integer multiples of the voxel
//! size in world space, so a grid does not shift when the scene grows. A
//! surface lying exactly in a voxel face belongs to the voxel its normal
//! points into (the kernel's `clip_piece`), so it is counted once. Pieces
//! smaller than [`MIN_PIECE_AREA`] voxel faces (slivers along a voxel edge)
//! occupy nothing; they are counted and their area reported.
//!
//! Memory is proportional to the number of pieces (occupied voxels times
//! triangles per voxel), never to the grid volume.

use crate::compute::Backend;
pub use crate::cover::{
    Cover, COVER_DISTANCE, COVER_GAP, COVER_POINTS, ENCLOSED_POLAR, ENCLOSED_RAYS,
};
use crate::error::BakeError;
use radiosity_core::patch::{AreaSpread, Grid, Patch, Region};
use radiosity_core::scene::Scene;
use serde::Serialize;
use std::time::Instant;

mod clip;
mod compare;
mod components;
pub mod fragments;
mod groups;
mod reduce;
mod staircase;
mod visibility;
pub use clip::{cl_pieces, cpu_pieces, grid_coords};
pub use compare::{compare, compare_pieces, Comparison, PieceComparison};
pub use reduce::reduce;

/// Lift of the connectivity segments' ends along their normals, in voxel
/// sizes: 8× the f32 rounding of BVH coordinates relative to the grid
/// centre (as the mesh map's and the surface map's segments).
pub const CONNECT_LIFT: f64 = 1e-3;

/// Reach, in voxel sizes, within which a triangle facing the pieces'
/// direction does not separate them (their own surface, curving across the
/// chord): a voxel's diagonal.
pub const CONNECT_OWN: f64 = 1.732_050_807_568_877_2;

/// Nearest pieces (or pairs of pieces) tested for connectivity.
pub const NEAREST: usize = 4;

/// Components smaller than this (in voxel faces) are relief, not separate
/// surfaces, when a segment lifted [`RELIEF_LIFT`] voxels joins them to
/// another component of their voxel and direction.
pub const SMALL_COMPONENT: f64 = 0.1;

/// The lift, in voxel sizes, under which relief does not separate small
/// components (module doc, "Connected surfaces").
pub const RELIEF_LIFT: f64 = 0.25;

pub use radiosity_core::polygon::stratified_points;

/// The kernel source, embedded.
pub const KERNEL_SOURCE: &str = include_str!("../../kernels/voxelize.cl");

/// Half size of the box in the overlap test; equals `SAT_HALF` in the kernel
/// (the margin keeps the f32 test conservative for grid coordinates up to
/// `MAX_DIM`, whose f32 rounding error is below 2.5e-4 voxels).
pub const SAT_HALF: f64 = 0.5005;

/// Pieces smaller than this (in voxel-face units) occupy no voxel: such
/// slivers come from a triangle grazing a voxel edge, and a value far above
/// f32 rounding of a piece's area (~1e-7) keeps the OpenCL and CPU results
/// in agreement.
pub const MIN_PIECE_AREA: f64 = 1e-6;

/// How the voxel size is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Resolution {
    /// An explicit voxel edge length in scene units.
    VoxelSize(f64),
    /// A target patch count: the voxel size is searched for (a few passes;
    /// the bake counts the patches the form factors will keep,
    /// [`voxelize_counting`]).
    Patches(usize),
}

/// One piece: the part of a triangle inside one voxel. `area` is in
/// voxel-face units; `centroid` is relative to the voxel's minimum corner.
/// The layout matches `Piece` in the kernel.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClPiece {
    pub tri: u32,
    pub voxel: [u32; 3],
    pub area: f32,
    pub centroid: [f32; 3],
}

/// A piece as the reduction sees it (f64 for both paths).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    pub tri: u32,
    pub voxel: [u32; 3],
    pub area: f64,
    pub centroid: [f64; 3],
}

/// Counts and times of one voxelization, for the bake summary.
#[derive(Clone, Debug, Default, Serialize)]
pub struct VoxelStats {
    pub voxel_size: f64,
    pub grid_dims: [u32; 3],
    pub triangles: u64,
    /// Voxel/triangle pairs passing the overlap test.
    pub candidate_pieces: u64,
    /// Pieces with area above `MIN_PIECE_AREA`.
    pub pieces: u64,
    /// Slivers below `MIN_PIECE_AREA`, and their total area (scene units²).
    pub sliver_pieces: u64,
    pub sliver_area: f64,
    pub occupied_voxels: u64,
    pub patches: u64,
    /// Patches facing +x, −x, +y, −y, +z, −z.
    pub patches_per_direction: [u64; 6],
    /// Voxel groups merged into their neighbour's (staircases).
    pub merged_groups: u64,
    /// Extra patches from voxel groups split where a surface separates
    /// their pieces (the two sides of a thin wall's floor, stacked floors).
    pub split_groups: u64,
    /// Patches far smaller than a voxel face joined to a neighbour that
    /// shares their light (module `fragments`).
    pub fragments_joined: u64,
    /// How evenly the patches share the area ([`AreaSpread`]).
    pub spread: AreaSpread,
    /// Pieces cut in two by a wall crossing them (module doc, "Pieces cut
    /// by a wall").
    pub cut_pieces: u64,
    /// Voxel groups facing a surface that looks back from the neighbour
    /// voxel: kept as patches (they receive light), counted.
    pub facing_back_groups: u64,
    /// Voxel groups dropped (none since facing groups are kept).
    pub covered_groups: u64,
    /// Covered geometry: pieces wholly covered (dropped), pieces partly
    /// covered (their covered share dropped), and the covered area in all
    /// and by facing direction (+x, −x, +y, −y, +z, −z).
    pub covered_pieces: u64,
    pub partly_covered_pieces: u64,
    pub covered_area: f64,
    pub covered_area_per_direction: [f64; 6],
    /// The part of `covered_area` on back sides (`Scene::twins`: every
    /// triangle's with `--two-sided`), and the back sides' whole area: a
    /// solid's back sides face its inside and are covered by design.
    pub covered_twin_area: f64,
    pub twin_area: f64,
    /// Patch albedo components outside [0, ALBEDO_MAX] after averaging, clamped.
    pub clamped_albedo: u64,
    /// Total patch area and total scene area (scene units²).
    pub patch_area: f64,
    pub scene_area: f64,
    /// Wall-clock seconds for the pieces (host view, including transfers),
    /// the device's kernel time (OpenCL only), and the reduction.
    pub seconds_pieces: f64,
    pub seconds_kernels: f64,
    pub seconds_reduce: f64,
    /// Voxel sizes tried while searching for a patch count, each with the
    /// count the search met the target on ([`voxelize_counting`]).
    pub search: Vec<(f64, u64)>,
}

/// The result: the grid, the patches (sorted by voxel key, then direction)
/// and the statistics.
#[derive(Clone, Debug)]
pub struct Voxelization {
    pub grid: Grid,
    pub patches: Vec<Patch>,
    /// Every piece above [`MIN_PIECE_AREA`], sorted by (triangle, voxel
    /// key), with the patch it went into (an index into `patches`), or
    /// `None` when its group was covered and dropped. The run time's
    /// surface map and the patches' sample points are built from these.
    pub pieces: Vec<OwnedPiece>,
    pub stats: VoxelStats,
}

/// A piece of a triangle in a voxel and the patch it belongs to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OwnedPiece {
    pub tri: u32,
    pub voxel: [u32; 3],
    pub patch: Option<u32>,
    /// The share of the piece's area that is not covered (module doc,
    /// "Covered geometry"): 0 for a dropped piece, 1 for most.
    pub visible: f32,
    /// For a part of a piece cut by a wall (module doc), its region (empty
    /// for a whole piece); the parts are adjacent in the list, in chain
    /// order.
    pub region: Region,
}

/// Voxelizes `scene` at the given resolution on `backend`; a patch-count
/// target counts the voxelization's patches ([`voxelize_counting`]).
pub fn voxelize(
    scene: &Scene,
    resolution: Resolution,
    backend: &Backend,
) -> Result<Voxelization, BakeError> {
    voxelize_counting(scene, resolution, backend, &|v| v.stats.patches)
}

/// Voxelizes `scene` at the given resolution on `backend`, a patch-count
/// target met on `count` of each pass (the bake counts the patches that
/// see another surface, which the form factors keep:
/// [`crate::form_factor::rays::seeing_patches`]). The search records each
/// pass's size and count ([`VoxelStats::search`]).
pub fn voxelize_counting(
    scene: &Scene,
    resolution: Resolution,
    backend: &Backend,
    count: &dyn Fn(&Voxelization) -> u64,
) -> Result<Voxelization, BakeError> {
    // The scene's largest extent: the finest grid the search may ask for,
    // and the scale an error without patches reports.
    let (lo, hi) = scene.bounds();
    let extent = (0..3)
        .map(|a| hi[a] as f64 - lo[a] as f64)
        .fold(0.0, f64::max);
    let v = match resolution {
        Resolution::VoxelSize(size) => voxelize_at(scene, size, backend)?,
        Resolution::Patches(target) => {
            if target == 0 {
                return Err(BakeError::InvalidOption {
                    option: "patch count",
                    value: "0".into(),
                    expected: "at least 1".into(),
                });
            }
            // A surface of area A gives about A / s² patches per side it is
            // seen from; start there and correct with the measured count,
            // which scales like s^-p: p = 2 at first, then the slope of the
            // last two passes in log-log (at coarse sizes relief splits into
            // more patches per voxel and p falls: Sponza's count went
            // 1,941 → 1,228 from 5.8 to 13.7 m, p ≈ 0.5, where assuming 2
            // stopped 23 % above a target of 1,000). A few passes reach
            // ±5 %.
            // The finest voxel the grid holds (`Grid::new`: the extent
            // over the size, plus up to 4 voxels of rounding and padding,
            // at most MAX_DIM): a scene whose area is small for its extent
            // (thin strips, slivers, wires, objects far apart) gets a first
            // guess finer than that, and the search goes on from the
            // finest grid instead of stopping at a refused one.
            let finest = extent / (radiosity_core::patch::MAX_DIM as f64 - 8.0);
            let mut size = (scene.surface_area() / target as f64).sqrt().max(finest);
            let mut search = Vec::new();
            let mut best: Option<(Voxelization, u64)> = None;
            // A pass is taken only if the share of the scene's area it
            // covers (module doc, "Covered geometry") has not collapsed:
            // at most twice the least any pass covered, plus 5 % of the
            // area. Hidden area grows slowly with the voxel size in real
            // scenes (the interior: 11 % at 0.69 m, 18 % at 14 m), but once
            // voxels are so coarse that the covering gap (COVER_GAP voxels)
            // spans a room, its floor and ceiling cover each other and
            // their light is lost (a room asked for 3 patches lost 40 % of
            // its area), however close the count is to the target. A pass
            // without patches is never taken.
            // Back sides (two-sided bakes, faces the winding check gave
            // one) are left out: a solid's insides are covered by design,
            // more of them as voxels grow, and counting them can refuse
            // every pass coarser than a fine first one (the likely cause of
            // a two-sided cathedral asked for 2,000 patches making 18,697).
            let share = |v: &Voxelization| {
                (v.stats.covered_area - v.stats.covered_twin_area).max(0.0)
                    / (v.stats.scene_area - v.stats.twin_area).max(f64::MIN_POSITIVE)
            };
            let err_of = |counted: u64| (counted as f64 / target as f64 - 1.0).abs();
            let mut least = f64::INFINITY;
            for _ in 0..8 {
                let v = voxelize_at(scene, size, backend)?;
                let counted = if v.stats.patches == 0 { 0 } else { count(&v) };
                search.push((size, counted));
                least = least.min(share(&v));
                let eligible =
                    |v: &Voxelization| v.stats.patches > 0 && share(v) <= 2.0 * least + 0.05;
                let (ok, err, empty) = (eligible(&v), err_of(counted), v.stats.patches == 0);
                let better = ok
                    && best
                        .as_ref()
                        .is_none_or(|(b, bc)| !eligible(b) || err < err_of(*bc));
                if better || best.is_none() {
                    best = Some((v, counted));
                }
                if empty {
                    // No count to correct from: smaller voxels.
                    if size <= finest {
                        break;
                    }
                    size = (size * 0.25).max(finest);
                    continue;
                }
                if ok && err < 0.05 {
                    break;
                }
                let step = search_step(&search, target);
                if step < 1.0 && size <= finest {
                    // More patches are asked for than the finest grid gives.
                    break;
                }
                size = (size * step).max(finest);
            }
            let (mut best, _) = best.expect("at least one pass ran");
            best.stats.search = search;
            best
        }
    };
    if v.stats.patches == 0 {
        return Err(BakeError::NoPatches {
            voxel_size: v.stats.voxel_size,
            pieces: v.stats.pieces,
            covered: v.stats.covered_pieces,
            slivers: v.stats.sliver_pieces,
            gap: COVER_GAP,
            extent,
        });
    }
    Ok(v)
}

/// The factor the voxel size is multiplied by after the passes `search`
/// (size, patches) for `target` patches: `(n / target)^(1/p)` with the
/// count's local exponent `p` (2 for the first pass, then from the last
/// two passes, held to [0.25, 4]), the step held to [1/4, 4].
fn search_step(search: &[(f64, u64)], target: usize) -> f64 {
    let [.., (s0, n0), (s1, n1)] = *search else {
        let n = search.last().map_or(1, |p| p.1.max(1));
        return (n as f64 / target as f64).sqrt().clamp(0.25, 4.0);
    };
    let slope = (n0.max(1) as f64 / n1.max(1) as f64).ln() / (s1 / s0).ln();
    let p = if slope.is_finite() && slope > 0.0 {
        slope.clamp(0.25, 4.0)
    } else {
        2.0
    };
    (n1.max(1) as f64 / target as f64)
        .powf(1.0 / p)
        .clamp(0.25, 4.0)
}

/// Voxelizes at one voxel size.
pub fn voxelize_at(scene: &Scene, size: f64, backend: &Backend) -> Result<Voxelization, BakeError> {
    let grid = Grid::new(scene.bounds(), size)?;
    let coords = grid_coords(scene, &grid);
    let start = Instant::now();
    let (pieces, seconds_kernels) = match backend {
        Backend::Cpu => (cpu_pieces(&coords, &grid), 0.0),
        Backend::OpenCl(gpu) => cl_pieces(gpu, &coords, &grid)?,
    };
    let seconds_pieces = start.elapsed().as_secs_f64();
    let mut v = reduce(scene, grid, &pieces)?;
    v.stats.seconds_pieces = seconds_pieces;
    v.stats.seconds_kernels = seconds_kernels;
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::search_step;

    /// Runs the search on a count `n(s) = c s^-p` and returns its passes.
    fn passes(p: f64, start: f64, target: usize) -> Vec<(f64, u64)> {
        let count = |s: f64| (4000.0 * s.powf(-p)).round() as u64;
        let mut size = start;
        let mut search = Vec::new();
        for _ in 0..6 {
            let n = count(size);
            search.push((size, n));
            if (n as f64 / target as f64 - 1.0).abs() < 0.05 {
                break;
            }
            size *= search_step(&search, target);
        }
        search
    }

    /// The patch count's exponent is 2 on open surfaces and falls to about
    /// 0.5 at coarse sizes on relief (Sponza, module doc of `voxelize`):
    /// the search reaches ±5 % of its target in six passes on both, where
    /// always assuming 2 ended at 1,389 for 1,000 with exponent 0.5.
    #[test]
    fn the_patch_count_search_follows_the_counts_slope() {
        for p in [2.0, 1.0, 0.5] {
            let search = passes(p, 1.0, 1000);
            let &(_, n) = search.last().unwrap();
            assert!(
                (n as f64 / 1000.0 - 1.0).abs() < 0.05,
                "exponent {p}: {search:?}"
            );
        }
        // With exponent 2 the first step lands on the target.
        assert_eq!(passes(2.0, 1.0, 1000).len(), 2);
    }
}

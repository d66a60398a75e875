//! Bake step 7: the per-pixel surface map and the patches' sample points
//! (the format and how the run time uses them: [`radiosity_bakefile::surface`]).
//!
//! **Sample points.** A patch stands for pieces of real triangles; its
//! direct light must be measured on them, not on its square (which can lie
//! inside relief or stick out past a wall's end). The pieces are projected
//! onto the patch's plane ([`radiosity_core::patch::PatchFrame`]); points of
//! the 2D Sobol' (0, 2)-sequence ([`radiosity_core::math::sobol02`]), digitally
//! shifted by a seeded value per patch, over the projection's bounding box
//! are kept when they fall inside a piece, and lifted back onto that
//! piece's triangle (the front-most piece along the patch normal where
//! pieces overlap in projection). The sequence is progressive, so every
//! prefix of the kept points is spread over the region, and deterministic.
//! Each point is moved to the centre of its 1/32 of the box along either
//! axis, which keeps it 1/64 of the box away from the edges. The first 8
//! and 16 points have one point in each eighth and sixteenth of the box
//! along either axis, which matters because shadow edges in
//! architecture are often parallel to a patch's sides: the R2 sequence
//! used before leaves the last 17.7 % of its first axis empty for 16
//! points (and so did every patch, in the same place), and on Sponza the
//! floor patches next to the sunlit courtyard, whose sun lay in a strip of
//! 0.5 m along that side, got no direct light at all (the floor's sunlit
//! power came out 14 % low at one voxel size, 5 % at another, and with it
//! the whole bake's indirect light). The shift per patch makes each
//! patch's estimate unbiased to within the centring, so the errors of a
//! row of patches along one shadow edge no longer add up. A region
//! covering less than 1/[`MAX_TRIES_PER_SAMPLE`] of its box (a thin diagonal
//! strip) fills the remaining samples with its pieces' centroids, counted.
//!
//! **Lattice neighbours.** For each patch and each of the eight in-plane
//! offsets, the patch facing the same way in the voxel at that offset (or
//! one voxel up or down along the facing axis, for surfaces that are tilted
//! or curved), with normals within 60° and a segment between the two
//! patches' first sample points (each lifted [`RAY_OFFSET`] voxels along
//! its normal) that crosses no triangle of the scene, except the surfaces
//! the two points lie on near the ends (triangles facing the patches'
//! direction within √3 voxels of an end: curved surfaces bulge across the
//! chord). A wall between them, of any thickness, blocks.
//!
//! **Pieces.** Every piece names its own patch when it has one in the
//! matrix. A piece whose group was dropped (covered) or whose patch was
//! removed (it saw nothing) gets a *substitute*: the nearest patch facing
//! the same way within two voxels whose sample point it sees; else none.
//! Both are counted, with their area.

use super::error::BakeError;
use super::pieces::{self, PieceGeo};
use super::voxelize::{Cover, Voxelization};
use radiosity_bakefile::surface::{
    offset_slot, MapPiece, PatchSamples, SurfaceMap, NONE, OFFSETS, PIECE_CUT, PIECE_SUBSTITUTE,
    SAMPLES_PER_PATCH,
};
use radiosity_core::bvh::Bvh;
use radiosity_core::math::{add, dot, norm, scale, sobol02, sub, SplitMix64};
use radiosity_core::patch::{Direction, Grid};
use radiosity_core::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::time::Instant;

/// Candidate points tried per sample point before the centroid fallback.
pub const MAX_TRIES_PER_SAMPLE: usize = 64;

/// Offset of visibility segments' ends along their normals, in voxel
/// sizes: 8× the f32 rounding of BVH coordinates (as the mesh map's).
pub const RAY_OFFSET: f64 = 1e-3;

/// Seed of the per-patch digital shifts of the sample points' sequence.
const SAMPLE_SEED: u64 = 0x5a3c_91e7_d2b4_0f61;

/// Counts and time of one build.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SurfaceMapStats {
    pub triangles: u64,
    pub pieces: u64,
    /// Pieces lit by their own patch, by a substitute, by none; and the
    /// scene area of the last two (scene units²).
    pub pieces_own: u64,
    pub pieces_substitute: u64,
    pub pieces_unmapped: u64,
    pub area_substitute: f64,
    pub area_unmapped: f64,
    /// Patches whose region was too thin for the sampler: samples filled
    /// with piece centroids.
    pub patches_centroid_samples: u64,
    /// Mean lattice neighbours per patch, and candidates refused because a
    /// surface lies between them.
    pub mean_neighbours: f64,
    pub neighbours_blocked: u64,
    pub seconds: f64,
}

/// A patch's sample points (position, unit normal) and whether the
/// centroid fallback filled some.
type Samples = (Vec<([f64; 3], [f64; 3])>, bool);

/// Builds the surface map and the sample points. `patch_index_of[i]` is the
/// matrix (file-order) index of voxelization patch `i`, or `None` when the
/// form-factor stage removed it; `n` is the matrix size.
pub fn build(
    scene: &Scene,
    vox: &Voxelization,
    patch_index_of: &[Option<u32>],
    n: usize,
) -> Result<(SurfaceMap, PatchSamples, SurfaceMapStats), BakeError> {
    let start = Instant::now();
    let grid = vox.grid;
    if grid.dims.iter().any(|&d| d > u16::MAX as u32) {
        return Err(BakeError::TooLarge {
            stage: "surface map",
            detail: format!("grid dims {:?} exceed the map's 16-bit voxels", grid.dims),
        });
    }
    let mut stats = SurfaceMapStats {
        triangles: scene.triangles.len() as u64,
        pieces: vox.pieces.len() as u64,
        ..Default::default()
    };
    let geo = pieces::geometry(scene, vox);

    // Matrix patch -> voxelization patch, and its pieces.
    let vox_of = pieces::vox_of(patch_index_of, n);
    if let Some(m) = vox_of.iter().position(|&v| v == usize::MAX) {
        return Err(BakeError::Mismatch {
            stage: "surface map",
            detail: format!("matrix patch {m} has no voxelization patch"),
        });
    }
    let mut by_patch: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (k, p) in vox.pieces.iter().enumerate() {
        if let Some(m) = p.patch.and_then(|i| patch_index_of[i as usize]) {
            by_patch[m as usize].push(k);
        }
    }

    let bvh = Bvh::build(
        &scene.positions,
        &scene.triangles,
        super::form_factor::shift_of(&grid),
    );
    let normals: Vec<[f64; 3]> = scene.triangle_normals();
    let cover = Cover::new(scene, &grid, &bvh, &normals);

    // Sample points.
    let per_patch: Vec<Samples> = (0..n)
        .into_par_iter()
        .map(|m| sample_patch(vox, vox_of[m], &by_patch[m], &geo, &cover))
        .collect();
    let mut samples = PatchSamples::default();
    for (pts, fallback) in &per_patch {
        stats.patches_centroid_samples += u64::from(*fallback);
        for (p, q) in pts {
            samples.position.push(p.map(|x| x as f32));
            samples.normal.push(q.map(|x| x as f32));
        }
    }

    let vis = Visibility {
        bvh: &bvh,
        size: grid.size,
    };

    // Lattice neighbours.
    let mut at_voxel: HashMap<(u64, Direction), Vec<u32>> = HashMap::new();
    for (m, &i) in vox_of.iter().enumerate() {
        let p = &vox.patches[i];
        at_voxel
            .entry((grid.key(p.voxel), p.direction))
            .or_default()
            .push(m as u32);
    }
    let first_sample = |m: usize| per_patch[m].0[0];
    let nb: Vec<([u32; 8], u64)> = (0..n)
        .into_par_iter()
        .map(|m| {
            let p = &vox.patches[vox_of[m]];
            let a = p.direction.axis();
            let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
            let mut out = [NONE; 8];
            let mut blocked = 0u64;
            for (slot, &(du, dv)) in OFFSETS.iter().enumerate() {
                'found: for k in [0i64, -1, 1] {
                    let mut v = p.voxel.map(|c| c as i64);
                    v[ua] += du as i64;
                    v[va] += dv as i64;
                    v[a] += k;
                    let Some(w) = in_grid(&grid, v) else { continue };
                    let Some(cands) = at_voxel.get(&(grid.key(w), p.direction)) else {
                        continue;
                    };
                    for &q in cands {
                        let pq = &vox.patches[vox_of[q as usize]];
                        if dot(p.normal, pq.normal) < 0.5 {
                            continue;
                        }
                        let (a0, n0) = first_sample(m);
                        let (b0, n1) = first_sample(q as usize);
                        if vis.clear(a0, n0, b0, n1, p.direction) {
                            out[slot] = q;
                            break 'found;
                        }
                        blocked += 1;
                    }
                }
            }
            debug_assert_eq!(offset_slot(OFFSETS[3].0, OFFSETS[3].1), 3);
            (out, blocked)
        })
        .collect();
    let mut neighbours = Vec::with_capacity(n);
    let mut count = 0u64;
    for (row, blocked) in nb {
        count += row.iter().filter(|&&x| x != NONE).count() as u64;
        stats.neighbours_blocked += blocked;
        neighbours.push(row);
    }
    stats.mean_neighbours = count as f64 / n.max(1) as f64;

    // Pieces and their patches.
    let owners: Vec<(u32, u16)> = vox
        .pieces
        .par_iter()
        .zip(&geo)
        .map(|(p, g)| {
            if let Some(m) = p.patch.and_then(|i| patch_index_of[i as usize]) {
                return (m, 0);
            }
            match substitute(&grid, &at_voxel, &vox_of, vox, &per_patch, &vis, p.voxel, g) {
                Some(m) => (m, PIECE_SUBSTITUTE),
                None => (NONE, 0),
            }
        })
        .collect();
    let mut tri_start = Vec::with_capacity(scene.triangles.len() + 1);
    let mut pieces = Vec::with_capacity(vox.pieces.len());
    let mut cuts = Vec::new();
    let mut k = 0usize;
    for t in 0..scene.triangles.len() as u32 {
        tri_start.push(pieces.len() as u32);
        while k < vox.pieces.len() && vox.pieces[k].tri == t {
            let (patch, flags) = owners[k];
            match (patch, flags) {
                (NONE, _) => {
                    stats.pieces_unmapped += 1;
                    stats.area_unmapped += geo[k].area;
                }
                (_, PIECE_SUBSTITUTE) => {
                    stats.pieces_substitute += 1;
                    stats.area_substitute += geo[k].area;
                }
                _ => stats.pieces_own += 1,
            }
            let cut_flag = match vox.pieces[k].region.own_cut() {
                Some(cut) => {
                    cuts.push((pieces.len() as u32, cut));
                    PIECE_CUT
                }
                None => 0,
            };
            pieces.push(MapPiece {
                voxel: vox.pieces[k].voxel.map(|c| c as u16),
                flags: flags | cut_flag,
                patch,
            });
            k += 1;
        }
    }
    tri_start.push(pieces.len() as u32);
    let map = SurfaceMap {
        origin: grid.origin,
        voxel_size: grid.size,
        dims: grid.dims,
        tri_start,
        pieces,
        patch_voxel: vox_of
            .iter()
            .map(|&i| vox.patches[i].voxel.map(|c| c as u16))
            .collect(),
        patch_direction: vox_of
            .iter()
            .map(|&i| vox.patches[i].direction as u8)
            .collect(),
        neighbours,
        cuts,
    };
    map.check(n).map_err(|detail| BakeError::Mismatch {
        stage: "surface map",
        detail: detail.to_string(),
    })?;
    stats.seconds = start.elapsed().as_secs_f64();
    Ok((map, samples, stats))
}

/// The voxel `v` if inside the grid.
fn in_grid(grid: &Grid, v: [i64; 3]) -> Option<[u32; 3]> {
    (0..3)
        .all(|k| v[k] >= 0 && v[k] < grid.dims[k] as i64)
        .then(|| v.map(|c| c as u32))
}

/// The sample points of one patch (module doc) and whether the centroid
/// fallback was needed.
fn sample_patch(
    vox: &Voxelization,
    i: usize,
    pieces: &[usize],
    geo: &[PieceGeo],
    cover: &Cover,
) -> Samples {
    let patch = &vox.patches[i];
    let f = patch.frame();
    // Pieces projected onto the patch plane (2D, relative to the centre),
    // with their triangle planes for lifting.
    struct Proj<'a> {
        pts: Vec<[f64; 2]>,
        orient: f64,
        g: &'a PieceGeo,
        cos: f64,
        /// The piece's triangle when the piece is partly covered: a point
        /// on its covered part is no sample (voxelize, "Covered geometry").
        partial: Option<u32>,
    }
    let mut projs = Vec::new();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &k in pieces {
        let g = &geo[k];
        let cos = dot(f.n, g.normal);
        if g.poly.len() < 3 || !(cos > 0.05) {
            continue;
        }
        let pts: Vec<[f64; 2]> = g
            .poly
            .iter()
            .map(|q| {
                let d = sub(*q, patch.centre);
                [dot(d, f.u), dot(d, f.v)]
            })
            .collect();
        for p in &pts {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let mut area2 = 0.0;
        for j in 0..pts.len() {
            let (p, q) = (pts[j], pts[(j + 1) % pts.len()]);
            area2 += p[0] * q[1] - q[0] * p[1];
        }
        if area2.abs() > 0.0 {
            let piece = &vox.pieces[k];
            projs.push(Proj {
                pts,
                orient: area2.signum(),
                g,
                cos,
                partial: (piece.visible < 1.0).then_some(piece.tri),
            });
        }
    }
    let mut out = Vec::with_capacity(SAMPLES_PER_PATCH);
    if !projs.is_empty() {
        let tries = MAX_TRIES_PER_SAMPLE * SAMPLES_PER_PATCH;
        // (The seed mixing is the one the figures in docs/accuracy.md were
        // measured with.)
        let r = SplitMix64::new(SAMPLE_SEED ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15))
            .next_u64();
        let shift = [r as u32, (r >> 32) as u32];
        for k in 0..tries {
            if out.len() == SAMPLES_PER_PATCH {
                break;
            }
            // At the centre of its 1/32 of the box along each axis: the
            // first 32 points keep one point per 1/32 (and the first 16 one
            // per 1/16), and no point comes closer than 1/64 of the box to
            // its edges, where a wall meets the surface (GL shadow maps
            // cannot resolve a point 0.1 mm from the wall that shades it).
            let s = sobol02(k as u32, shift).map(|c| ((c * 32.0).floor() + 0.5) / 32.0);
            let x = [
                lo[0] + s[0] * (hi[0] - lo[0]),
                lo[1] + s[1] * (hi[1] - lo[1]),
            ];
            let mut best: Option<(f64, &Proj)> = None;
            for pr in &projs {
                let inside = (0..pr.pts.len()).all(|j| {
                    let (p, q) = (pr.pts[j], pr.pts[(j + 1) % pr.pts.len()]);
                    let c = (q[0] - p[0]) * (x[1] - p[1]) - (q[1] - p[1]) * (x[0] - p[0]);
                    c * pr.orient >= 0.0
                });
                if !inside {
                    continue;
                }
                // Height along the patch normal where the line through x
                // meets the piece's plane.
                let base = add(patch.centre, add(scale(f.u, x[0]), scale(f.v, x[1])));
                let h = dot(sub(pr.g.poly[0], base), pr.g.normal) / pr.cos;
                if best.is_none_or(|(bh, _)| h > bh) {
                    best = Some((h, pr));
                }
            }
            if let Some((h, pr)) = best {
                let base = add(patch.centre, add(scale(f.u, x[0]), scale(f.v, x[1])));
                let y = add(base, scale(f.n, h));
                if pr
                    .partial
                    .is_some_and(|tri| cover.covered(y, pr.g.normal, tri))
                {
                    continue;
                }
                out.push((y, pr.g.normal));
            }
        }
    }
    let fallback = out.len() < SAMPLES_PER_PATCH;
    if fallback {
        // Centroids, largest pieces first, cycled.
        let mut order: Vec<usize> = pieces.to_vec();
        order.sort_by(|&a, &b| geo[b].area.total_cmp(&geo[a].area).then(a.cmp(&b)));
        if order.is_empty() {
            out.resize(SAMPLES_PER_PATCH, (patch.centre, f.n));
        } else {
            let mut j = 0;
            while out.len() < SAMPLES_PER_PATCH {
                let g = &geo[order[j % order.len()]];
                out.push((g.centroid, g.normal));
                j += 1;
            }
        }
    }
    (out, fallback)
}

/// Segment tests against the scene's triangles.
struct Visibility<'a> {
    bvh: &'a Bvh,
    size: f64,
}

impl Visibility<'_> {
    /// Whether the segment between `a` and `b` crosses no surface other
    /// than the ends' own (module doc; [`Bvh::surface_segment_clear`]).
    fn clear(&self, a: [f64; 3], na: [f64; 3], b: [f64; 3], nb: [f64; 3], dir: Direction) -> bool {
        self.bvh.surface_segment_clear(
            a,
            na,
            b,
            nb,
            RAY_OFFSET * self.size,
            3f64.sqrt() * self.size,
            dir as u32,
        )
    }
}

/// The substitute patch of a piece without one (module doc).
#[allow(clippy::too_many_arguments)]
fn substitute(
    grid: &Grid,
    at_voxel: &HashMap<(u64, Direction), Vec<u32>>,
    vox_of: &[usize],
    vox: &Voxelization,
    per_patch: &[Samples],
    vis: &Visibility,
    voxel: [u32; 3],
    g: &PieceGeo,
) -> Option<u32> {
    let dir = Direction::dominant(g.normal);
    let mut best: Option<(f64, u32)> = None;
    for r in 0..=2i64 {
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                        continue;
                    }
                    let v = [
                        voxel[0] as i64 + dx,
                        voxel[1] as i64 + dy,
                        voxel[2] as i64 + dz,
                    ];
                    let Some(w) = in_grid(grid, v) else { continue };
                    let Some(cands) = at_voxel.get(&(grid.key(w), dir)) else {
                        continue;
                    };
                    for &m in cands {
                        let p = &vox.patches[vox_of[m as usize]];
                        if dot(p.normal, g.normal) < 0.5 {
                            continue;
                        }
                        let d = norm(sub(p.centre, g.centroid));
                        if best.is_some_and(|(bd, bm)| (bd, bm) <= (d, m)) {
                            continue;
                        }
                        let (b, nb) = per_patch[m as usize].0[0];
                        if vis.clear(g.centroid, g.normal, b, nb, dir) {
                            best = Some((d, m));
                        }
                    }
                }
            }
        }
        if best.is_some() {
            break;
        }
    }
    best.map(|b| b.1)
}

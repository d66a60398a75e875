//! The reduction of pieces to patches (module doc of [`super`]): a
//! pipeline of named phases, each in its own file or function, with typed
//! hand-offs:
//! 1. [`keep`]: finite pieces of more than [`MIN_PIECE_AREA`], sorted by
//!    (voxel, direction, triangle); slivers counted;
//! 2. [`cut`]: pieces a thin wall crosses become their parts
//!    ([`crate::cut`]);
//! 3. [`visibility::split_covered`]: covered shares, wholly covered pieces
//!    set aside;
//! 4. [`components::split`]: connected components per voxel and direction;
//! 5. [`staircase::chain_ends`]: the neighbour rule's chains;
//! 6. [`join_fragments`]: small chain ends join a neighbour
//!    ([`fragments`]);
//! 7. [`assemble`]: each end's sums become a patch, each piece gets its
//!    owner.

use super::components::{self, Components};
use super::groups::{Acc, Geometry, Kept};
use super::visibility::{self, Visible};
use super::{
    fragments, grid_coords, staircase, OwnedPiece, Piece, VoxelStats, Voxelization, CONNECT_LIFT,
    CONNECT_OWN, MIN_PIECE_AREA,
};
use crate::error::BakeError;
use radiosity_core::bvh::Bvh;
use radiosity_core::math::dot;
use radiosity_core::patch::{AreaSpread, Direction, Grid, Patch, Region};
use radiosity_core::scene::Scene;
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};
use std::time::Instant;

/// Groups pieces into patches (the module doc gives the rules). Shared by
/// the CPU and OpenCL paths; deterministic: pieces are sorted by (voxel,
/// direction, triangle) before any sum.
pub fn reduce(scene: &Scene, grid: Grid, pieces: &[Piece]) -> Result<Voxelization, BakeError> {
    let start = Instant::now();
    let mut stats = VoxelStats {
        voxel_size: grid.size,
        grid_dims: grid.dims,
        triangles: scene.triangles.len() as u64,
        candidate_pieces: pieces.len() as u64,
        scene_area: scene.surface_area(),
        ..Default::default()
    };
    // Back sides are the last triangles (`Scene::twins`).
    stats.twin_area = (scene.own_triangles()..scene.triangles.len())
        .map(|t| scene.triangle_area(t))
        .sum();
    // Per-triangle unit normal (f64, from the winding).
    let normals: Vec<[f64; 3]> = scene.triangle_normals();
    let kept = keep(&grid, pieces, &normals, &mut stats)?;
    let bvh = Bvh::build(&scene.positions, &scene.triangles, grid.centre());
    let g = Geometry {
        scene,
        grid: &grid,
        bvh: &bvh,
        normals: &normals,
        lift: CONNECT_LIFT * grid.size,
        own: CONNECT_OWN * grid.size,
    };
    let coords = grid_coords(scene, &grid);
    let (pieces, regions, kept) = cut(&g, &coords, pieces, kept, &mut stats);
    stats.pieces = kept.len() as u64;
    // Which directions each voxel holds (bit `d`).
    let mut holds: HashMap<u64, u8> = HashMap::new();
    for &(key, dir, _, _) in &kept {
        *holds.entry(key).or_default() |= 1 << dir as u8;
    }
    stats.occupied_voxels = holds.len() as u64;
    let vis = visibility::split_covered(&g, &coords, &pieces, &regions, &kept, &mut stats);
    let comps = components::split(&g, &pieces, &vis, &mut stats);
    let ends = staircase::chain_ends(&g, &comps, &holds, &mut stats);
    let ends = join_fragments(&g, &comps, &ends, &mut stats);
    let (patches, pieces) = assemble(&g, &pieces, &regions, vis, &comps, &ends, &mut stats)?;
    stats.patches = patches.len() as u64;
    stats.spread = AreaSpread::of(patches.iter().map(|p| p.area), grid.size);
    stats.seconds_reduce = start.elapsed().as_secs_f64();
    Ok(Voxelization {
        grid,
        patches,
        pieces,
        stats,
    })
}

/// The pieces that take part: finite ones of more than [`MIN_PIECE_AREA`]
/// (of a voxel face), sorted by (voxel, direction, triangle); smaller
/// ones are counted as slivers. A non-finite piece is an error.
fn keep(
    grid: &Grid,
    pieces: &[Piece],
    normals: &[[f64; 3]],
    stats: &mut VoxelStats,
) -> Result<Vec<Kept>, BakeError> {
    let s2 = grid.size * grid.size;
    let mut kept: Vec<Kept> = Vec::with_capacity(pieces.len());
    for (i, p) in pieces.iter().enumerate() {
        if !p.area.is_finite() || !p.centroid.iter().all(|c| c.is_finite()) {
            return Err(BakeError::Numeric {
                stage: "voxelize",
                detail: format!(
                    "non-finite piece of triangle {} in voxel {:?}: area {}, centroid {:?}",
                    p.tri, p.voxel, p.area, p.centroid
                ),
            });
        }
        if p.area > MIN_PIECE_AREA {
            kept.push((
                grid.key(p.voxel),
                Direction::dominant(normals[p.tri as usize]),
                p.tri,
                i,
            ));
        } else if p.area > 0.0 {
            stats.sliver_pieces += 1;
            stats.sliver_area += p.area * s2;
        }
    }
    kept.sort_unstable();
    Ok(kept)
}

/// Pieces cut by a wall (module doc of [`super`]): each cut piece is
/// replaced by its parts, appended to the piece list with their regions.
/// Returns the pieces, their regions and the kept list, still sorted.
fn cut(
    g: &Geometry,
    coords: &[[f64; 9]],
    pieces: &[Piece],
    kept: Vec<Kept>,
    stats: &mut VoxelStats,
) -> (Vec<Piece>, Vec<Region>, Vec<Kept>) {
    let (grid, bvh, normals, lift, own) = (g.grid, g.bvh, g.normals, g.lift, g.own);
    // Pieces cut by a wall (module doc): each cut piece is replaced by its
    // parts, appended to the piece list with their regions.
    let cuts: Vec<Option<Vec<crate::cut::Part>>> = kept
        .par_iter()
        .map(|&(_, dir, tri, i)| {
            crate::cut::cut_piece(
                grid,
                coords,
                (tri, pieces[i].voxel),
                normals[tri as usize],
                dir,
                bvh,
                (lift, own),
                normals,
                MIN_PIECE_AREA,
            )
        })
        .collect();
    let mut all: Vec<Piece> = pieces.to_vec();
    let mut regions: Vec<Region> = vec![Region::default(); pieces.len()];
    let mut cut_kept = Vec::with_capacity(kept.len());
    for (&(key, dir, tri, i), cut) in kept.iter().zip(&cuts) {
        match cut {
            None => cut_kept.push((key, dir, tri, i)),
            Some(parts) => {
                stats.cut_pieces += 1;
                for &(region, area, centroid) in parts {
                    all.push(Piece {
                        area,
                        centroid,
                        ..pieces[i]
                    });
                    regions.push(region);
                    cut_kept.push((key, dir, tri, all.len() - 1));
                }
            }
        }
    }
    (all, regions, cut_kept)
}

/// Fragments (module [`fragments`]): the chains' ends are the patches so
/// far; those far smaller than a voxel face join a neighbour that shares
/// their light. Returns each component's final end.
fn join_fragments(
    g: &Geometry,
    c: &Components,
    target: &[usize],
    stats: &mut VoxelStats,
) -> Vec<usize> {
    let comps = &c.comps;
    let mut group_of_end: HashMap<usize, usize> = HashMap::new();
    let mut end_of_group: Vec<usize> = Vec::new();
    let mut groups: Vec<fragments::Group> = Vec::new();
    for (k, comp) in comps.iter().enumerate() {
        if target[k] != k {
            stats.merged_groups += 1;
        }
        let gi = *group_of_end.entry(target[k]).or_insert_with(|| {
            end_of_group.push(target[k]);
            groups.push(fragments::Group {
                dir: comp.dir,
                voxels: Vec::new(),
                area: 0.0,
                members: Vec::new(),
            });
            groups.len() - 1
        });
        groups[gi].voxels.push(comp.voxel);
        groups[gi].area += comp.host_area;
        groups[gi].members.extend(comp.members.iter().copied());
    }
    let (ends, joined) = fragments::join(&groups, g.grid, g.bvh);
    stats.fragments_joined = joined;
    (0..comps.len())
        .map(|k| end_of_group[ends[group_of_end[&target[k]]]])
        .collect()
}

/// Each chain end's sums become a patch (in the order of (voxel,
/// direction, component)); each visible piece gets its end's patch, the
/// covered ones none. Returns the patches and the owned pieces, in chain
/// order per triangle.
fn assemble(
    g: &Geometry,
    pieces: &[Piece],
    regions: &[Region],
    vis: Visible,
    c: &Components,
    target: &[usize],
    stats: &mut VoxelStats,
) -> Result<(Vec<Patch>, Vec<OwnedPiece>), BakeError> {
    let (grid, comps) = (g.grid, &c.comps);
    let (kept, visible_share, hidden_pieces) = (&vis.kept, &vis.share, vis.hidden);
    let mut targets: BTreeMap<(u64, Direction, u32), ([u32; 3], Acc)> = BTreeMap::new();
    for (k, comp) in comps.iter().enumerate() {
        let tgt = &comps[target[k]];
        targets
            .entry((tgt.key, tgt.dir, tgt.local))
            .or_insert((tgt.voxel, Acc::default()))
            .1
            .add(&comp.acc);
    }
    let patch_of: HashMap<(u64, Direction, u32), u32> = targets
        .keys()
        .enumerate()
        .map(|(i, k)| (*k, i as u32))
        .collect();
    // Pieces with their owner.
    let mut pieces: Vec<OwnedPiece> = kept
        .iter()
        .enumerate()
        .map(|(idx, &(_, _, tri, i))| {
            let t = &comps[target[c.of_kept[idx]]];
            OwnedPiece {
                tri,
                voxel: pieces[i].voxel,
                patch: Some(patch_of[&(t.key, t.dir, t.local)]),
                visible: visible_share[idx] as f32,
                region: regions[i],
            }
        })
        .collect();
    pieces.extend(hidden_pieces);
    // The parts of a cut piece in chain order.
    pieces.sort_unstable_by_key(|p| (p.tri, grid.key(p.voxel), p.region.position()));
    let mut patches = Vec::with_capacity(targets.len());
    for ((_, dir, _), (voxel, acc)) in targets {
        let len = dot(acc.area_normal, acc.area_normal).sqrt();
        if !(len > 0.0) {
            // Pieces facing one direction cannot cancel (their normals'
            // `d` components are all positive); keep the invariant checked.
            return Err(BakeError::Numeric {
                stage: "voxelize",
                detail: format!("patch in voxel {voxel:?} facing {} has no area", dir.name()),
            });
        }
        let m = acc.area_normal.map(|c| c / len);
        // Weights `A_t (n_t · m)` summed: `(Σ A_t n_t) · m = |Σ A_t n_t|`.
        let weight = len;
        let mut albedo: [f64; 3] = std::array::from_fn(|c| dot(acc.albedo_normal[c], m) / weight);
        // Within one facing direction the weights are positive except for
        // normals at exact 45° ties pointing apart; the average can then
        // leave [0, ALBEDO_MAX], and is clamped and counted.
        for a in &mut albedo {
            let clamped = a.clamp(0.0, radiosity_core::scene::ALBEDO_MAX as f64);
            if clamped != *a {
                stats.clamped_albedo += 1;
                *a = clamped;
            }
        }
        patches.push(Patch {
            centre: acc.moment.map(|c| c / acc.area),
            normal: m,
            area: len,
            albedo,
            emission: std::array::from_fn(|c| (dot(acc.emission_normal[c], m) / weight).max(0.0)),
            voxel,
            direction: dir,
        });
        stats.patches_per_direction[dir as usize] += 1;
        stats.patch_area += len;
    }
    Ok((patches, pieces))
}

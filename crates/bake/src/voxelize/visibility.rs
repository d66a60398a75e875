//! The reduction's covered-geometry phase (module doc of [`super`],
//! "Covered geometry"): the share of each piece whose points another
//! surface covers, the point that stands for the piece in the
//! connectivity tests, and its visible area from the host's coordinates.
//! Wholly covered pieces leave the reduction (they keep no patch).

use super::groups::{Geometry, Kept};
use super::{OwnedPiece, Piece, VoxelStats, COVER_POINTS};
use crate::cover::Cover;
use radiosity_core::math::{dot, sub};
use radiosity_core::patch::{piece_polygon, Region};
use radiosity_core::polygon::stratified_points;
use rayon::prelude::*;

/// The pieces that are seen, at least in part, and those that are not.
pub(super) struct Visible {
    /// The kept pieces not wholly covered, in their order.
    pub(super) kept: Vec<Kept>,
    /// Per visible piece: its visible share, the point standing for it,
    /// and its visible area from the host's coordinates (scene units²).
    pub(super) share: Vec<f64>,
    pub(super) point: Vec<[f64; 3]>,
    pub(super) host_area: Vec<f64>,
    /// The wholly covered pieces, with no patch.
    pub(super) hidden: Vec<OwnedPiece>,
}

/// Splits `kept` (indices into `pieces`, whose regions are `regions`) into
/// the visible and the covered, counting areas in `stats`. `coords`: the
/// triangles' grid coordinates ([`super::grid_coords`]).
pub(super) fn split_covered(
    g: &Geometry,
    coords: &[[f64; 9]],
    pieces: &[Piece],
    regions: &[Region],
    kept: &[Kept],
    stats: &mut VoxelStats,
) -> Visible {
    let (scene, grid, bvh, normals) = (g.scene, g.grid, g.bvh, g.normals);
    let s2 = grid.size * grid.size;
    // Back sides are the last triangles (`Scene::twins`).
    let first_twin = scene.own_triangles();
    // Covered geometry (module doc, "Covered geometry"): the share of each
    // piece with another surface within COVER_DISTANCE voxels in front.
    let cover_test = Cover::new(scene, grid, bvh, normals);
    // Per piece: the covered share of its points, and the point that
    // stands for it in the connectivity tests below: its polygon's vertex
    // mean (from the host's grid coordinates, the same on every backend),
    // or where a part of it is covered, its first visible point (a floor
    // triangle reaching under a box belongs with the floor outside it,
    // where it is seen).
    let covered: Vec<(f64, [f64; 3], f64)> = kept
        .par_iter()
        .map(|&(_, _, tri, i)| {
            let p = &pieces[i];
            let n = normals[tri as usize];
            // The polygon's vertex mean, from the host's grid coordinates
            // (not the kernel's centroid), so both backends test the same
            // points.
            let poly = piece_polygon(grid, &coords[tri as usize], p.voxel, &regions[i]);
            let c: [f64; 3] = if poly.is_empty() {
                std::array::from_fn(|q| {
                    grid.origin[q] + grid.size * (p.voxel[q] as f64 + p.centroid[q])
                })
            } else {
                std::array::from_fn(|q| poly.iter().map(|v| v[q]).sum::<f64>() / poly.len() as f64)
            };
            let mut points = stratified_points(&poly, COVER_POINTS);
            if points.is_empty() {
                points.push(c);
            }
            // And its corners: a sliver of the piece that a wall leaves
            // outside (a floor piece cut by a box 0.01 voxels inside its
            // voxel) has no stratified point, but a corner; dropping it
            // would lose the light that reaches it. Every point is pulled
            // 1 % towards the centroid: a point on the piece's edge may lie
            // in the plane of a wall standing there, where it is neither
            // inside nor outside.
            points.extend(poly.iter().copied());
            for x in &mut points {
                *x = std::array::from_fn(|q| x[q] + 0.01 * (c[q] - x[q]));
            }
            let hidden: Vec<bool> = points
                .iter()
                .map(|&x| cover_test.covered(x, n, tri))
                .collect();
            let share = hidden.iter().filter(|&&h| h).count() as f64 / points.len() as f64;
            let seen = hidden.iter().position(|&h| !h).map(|k| points[k]);
            // The polygon's area from the host's coordinates (the same on
            // every backend, for the fragments' decisions), else the
            // piece's.
            let host_area = if poly.len() >= 3 {
                let mut sum = [0.0f64; 3];
                for k in 0..poly.len() {
                    let x = radiosity_core::math::cross(
                        sub(poly[k], poly[0]),
                        sub(poly[(k + 1) % poly.len()], poly[0]),
                    );
                    for q in 0..3 {
                        sum[q] += x[q];
                    }
                }
                0.5 * dot(sum, sum).sqrt()
            } else {
                p.area * s2
            };
            (
                share,
                if share > 0.0 { seen.unwrap_or(c) } else { c },
                host_area,
            )
        })
        .collect();
    let mut hidden_pieces: Vec<OwnedPiece> = Vec::new();
    let mut visible = Vec::with_capacity(kept.len());
    let mut visible_share = Vec::with_capacity(kept.len());
    let mut visible_point = Vec::with_capacity(kept.len());
    let mut visible_host_area = Vec::with_capacity(kept.len());
    for (k, &(key, dir, tri, i)) in kept.iter().enumerate() {
        let (covered_share, seen, host_area) = covered[k];
        let a = pieces[i].area * s2 * covered_share;
        stats.covered_area += a;
        stats.covered_area_per_direction[dir as usize] += a;
        if tri as usize >= first_twin {
            stats.covered_twin_area += a;
        }
        if covered_share >= 1.0 {
            stats.covered_pieces += 1;
            hidden_pieces.push(OwnedPiece {
                tri,
                voxel: pieces[i].voxel,
                patch: None,
                visible: 0.0,
                region: regions[i],
            });
        } else {
            stats.partly_covered_pieces += u64::from(covered_share > 0.0);
            visible.push((key, dir, tri, i));
            visible_share.push(1.0 - covered_share);
            visible_point.push(seen);
            visible_host_area.push(host_area * (1.0 - covered_share));
        }
    }
    Visible {
        kept: visible,
        share: visible_share,
        point: visible_point,
        host_area: visible_host_area,
        hidden: hidden_pieces,
    }
}

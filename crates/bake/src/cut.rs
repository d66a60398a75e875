//! Pieces cut by a wall (bake step 2, called by the voxelizer's
//! reduction, [`crate::voxelize`]).
//!
//! A piece is all of a triangle inside one voxel, so a big floor triangle
//! under a wall thinner than a voxel gives one piece on both sides of the
//! wall: the voxelizer's component split cannot separate it, and its patch gathered light in the lit room and sent it
//! into the dark one (a 2-triangle floor under a 1 mm wall at an arbitrary
//! place: 30 % of the lit side's peak on the dark side). So before
//! anything else each piece is tested: when a segment from its vertex mean
//! to one of its corners (pulled 2 % inwards), lifted as in the component
//! test, crosses a surface transverse to it, the piece is cut by that
//! surface's plane ([`Cut`]). The cut stands when both sides have area
//! above the voxelizer's smallest piece and no pair of their points (the
//! [`CUT_POINTS`] stratified points of one and the nearest of the other's)
//! is connected — a column standing on the floor inside the voxel cuts
//! nothing, the floor joins around it. The side that another wall still
//! crosses is cut again (a wall thinner than a voxel has both faces in
//! it), up to [`MAX_CUTS`] times: a chain of parts, each a piece of its
//! own from then on (the same triangle and voxel, with its [`Region`]): it
//! joins components, is covered, casts rays and is lit on its own side;
//! the surface map stores the cuts so the run time picks the part a point
//! lies in. Counted (`cut_pieces`).
//!
//! The cut planes are the blocking triangles' planes in the voxel's own
//! coordinates, stored f32 ([`Cut`]), so the bake and the run time split
//! at the same place.

use radiosity_core::bvh::{Blocker, Bvh};
use radiosity_core::math::{dot, sub};
use radiosity_core::patch::{
    clip_side, piece_polygon_local, Cut, Direction, Grid, Region, MAX_CUTS,
};
use radiosity_core::polygon::{polygon_area_centroid, stratified_points};

/// Points per half of a cut piece tested for connectivity (module doc,
/// "Pieces cut by a wall").
pub const CUT_POINTS: usize = 8;

/// The triangle crossing a segment from the vertex mean of `local` (a
/// voxel-local polygon of a piece with unit normal `n`) to one of its
/// corners, transverse to the piece (module doc, "Pieces cut by a wall").
#[allow(clippy::too_many_arguments)]
fn wall_across(
    local: &[[f64; 3]],
    world: &dyn Fn([f64; 3]) -> [f64; 3],
    n: [f64; 3],
    dir: Direction,
    bvh: &Bvh,
    (lift, own): (f64, f64),
    normals: &[[f64; 3]],
) -> Option<u32> {
    if local.len() < 3 {
        return None;
    }
    let c: [f64; 3] =
        std::array::from_fn(|q| local.iter().map(|v| v[q]).sum::<f64>() / local.len() as f64);
    local.iter().find_map(|v| {
        let x: [f64; 3] = std::array::from_fn(|q| v[q] + 0.02 * (c[q] - v[q]));
        match bvh.surface_segment_blocker(world(c), n, world(x), n, lift, own, dir as u32) {
            Blocker::Triangle(t) if dot(normals[t as usize], n).abs() < 0.9 => Some(t),
            _ => None,
        }
    })
}

/// One part of a cut piece: its region, and its area (voxel faces) and
/// centroid (relative to the voxel's minimum corner, voxel units).
pub type Part = (Region, f64, [f64; 3]);

/// The chain of cuts of triangle `tri`'s piece in `voxel`, the triangle
/// with unit normal `n` facing `dir` (module doc, "Pieces cut by a wall"):
/// its parts in chain order, or `None` when no wall cuts it. Parts need an
/// area above `min_area` (voxel faces).
#[allow(clippy::too_many_arguments)]
pub fn cut_piece(
    grid: &Grid,
    coords: &[[f64; 9]],
    (tri, voxel): (u32, [u32; 3]),
    n: [f64; 3],
    dir: Direction,
    bvh: &Bvh,
    reach: (f64, f64),
    normals: &[[f64; 3]],
    min_area: f64,
) -> Option<Vec<Part>> {
    let world = |l: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|q| grid.origin[q] + grid.size * (voxel[q] as f64 + l[q]))
    };
    let whole = piece_polygon_local(&coords[tri as usize], voxel, &Region::default());
    let mut parts: Vec<Part> = Vec::new();
    let mut rest = Region::default();
    let mut rest_poly = whole;
    let mut rest_area = (0.0, [0.0; 3]);
    while parts.len() < MAX_CUTS {
        let Some(blocker) = wall_across(&rest_poly, &world, n, dir, bvh, reach, normals) else {
            break;
        };
        // The blocking triangle's plane in this voxel's coordinates.
        let nb = normals[blocker as usize].map(|x| x as f32);
        let v0: [f64; 3] = std::array::from_fn(|q| coords[blocker as usize][q] - voxel[q] as f64);
        let mut cut = Cut {
            n: nb,
            d: (0..3).map(|q| nb[q] as f64 * v0[q]).sum::<f64>() as f32,
        };
        let mut sides = [true, false].map(|positive| clip_side(&rest_poly, cut, positive));
        let mut areas = [0, 1].map(|k| polygon_area_centroid(&sides[k], n));
        if !(areas[0].0 > min_area && areas[1].0 > min_area)
            || halves_connected(&sides, &world, n, dir, bvh, reach)
        {
            break;
        }
        // The side another wall still crosses continues the chain (the
        // negative one): a wall thinner than a voxel has both faces in it.
        let more = |poly: &[[f64; 3]]| wall_across(poly, &world, n, dir, bvh, reach, normals);
        if more(&sides[0]).is_some() && more(&sides[1]).is_none() {
            cut = Cut {
                n: cut.n.map(|x| -x),
                d: -cut.d,
            };
            sides.swap(0, 1);
            areas.swap(0, 1);
        }
        parts.push((rest.with(cut, true)?, areas[0].0, areas[0].1));
        rest = rest.with(cut, false)?;
        rest_poly = std::mem::take(&mut sides[1]);
        rest_area = areas[1];
    }
    if parts.is_empty() {
        return None;
    }
    parts.push((rest, rest_area.0, rest_area.1));
    Some(parts)
}

/// Whether the two sides of a cut (voxel-local polygons) are connected
/// around the wall's end (a column, a doorway's jamb): then the wall does
/// not separate them. Stratified points of one, each with the nearest of
/// the other's.
fn halves_connected(
    sides: &[Vec<[f64; 3]>; 2],
    world: &dyn Fn([f64; 3]) -> [f64; 3],
    n: [f64; 3],
    dir: Direction,
    bvh: &Bvh,
    (lift, own): (f64, f64),
) -> bool {
    // Points pulled 5 % towards their side's vertex mean: a stratified
    // point can lie on the side's edge, on the cut itself, where a segment
    // would end in the wall's plane and miss it.
    let points = |local: &[[f64; 3]]| {
        let poly: Vec<[f64; 3]> = local.iter().map(|&v| world(v)).collect();
        let mut pts = stratified_points(&poly, CUT_POINTS);
        let m: [f64; 3] =
            std::array::from_fn(|q| poly.iter().map(|v| v[q]).sum::<f64>() / poly.len() as f64);
        for x in &mut pts {
            *x = std::array::from_fn(|q| x[q] + 0.05 * (m[q] - x[q]));
        }
        pts.push(m);
        pts
    };
    let (a, b) = (points(&sides[0]), points(&sides[1]));
    a.iter().any(|&x| {
        let y = b.iter().copied().min_by(|u, v| {
            radiosity_core::math::norm(sub(*u, x))
                .total_cmp(&radiosity_core::math::norm(sub(*v, x)))
        });
        y.is_some_and(|y| bvh.surface_segment_clear(x, n, y, n, lift, own, dir as u32))
    })
}

//! The real surface behind each patch: the pieces of triangles in voxels
//! that the voxelizer grouped into it ([`super::voxelize::OwnedPiece`]),
//! with their polygons, and the lookup from a point of a triangle to its
//! piece. Form factors shoot rays from these pieces and credit what the rays
//! hit to the hit piece's patch; the surface map and the sample points are
//! built from them too.

use super::voxelize::{grid_coords, Voxelization};
use radiosity_core::patch::piece_polygon;
use radiosity_core::scene::Scene;
use rayon::prelude::*;

/// How far (voxel sizes) the geometry of a part of a cut piece stays from
/// its cuts ([`geometry`]): the voxelizer's connectivity lift, far above
/// the f32 rounding of BVH coordinates, far below anything lit.
pub const CUT_INSET: f32 = 1e-3;

/// One piece with its geometry (world coordinates).
#[derive(Clone, Debug)]
pub struct PieceGeo {
    /// The convex polygon of the triangle inside the voxel.
    pub poly: Vec<[f64; 3]>,
    /// The triangle's unit normal (from its winding).
    pub normal: [f64; 3],
    pub area: f64,
    pub centroid: [f64; 3],
}

/// The geometry of every piece of `vox`, in `vox.pieces` order (of a part
/// of a cut piece, [`CUT_INSET`] inside its region).
pub fn geometry(scene: &Scene, vox: &Voxelization) -> Vec<PieceGeo> {
    let coords = grid_coords(scene, &vox.grid);
    vox.pieces
        .par_iter()
        .map(|p| {
            // A cut part is taken [`CUT_INSET`] voxels away from its cuts:
            // a ray cast from the foot of the wall that cut it would start
            // in the wall's plane and pass it.
            let region = p.region.inset(CUT_INSET);
            let poly = piece_polygon(&vox.grid, &coords[p.tri as usize], p.voxel, &region);
            let normal = scene.triangle_normal(p.tri as usize);
            let (area, centroid) = polygon_area_centroid(&poly, normal);
            PieceGeo {
                poly,
                normal,
                area,
                centroid,
            }
        })
        .collect()
}

pub use radiosity_core::polygon::polygon_area_centroid;

/// The piece indices of each voxelization patch.
pub fn by_patch(vox: &Voxelization) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); vox.patches.len()];
    for (k, p) in vox.pieces.iter().enumerate() {
        if let Some(i) = p.patch {
            out[i as usize].push(k);
        }
    }
    out
}

/// Per matrix patch (`0..n`), its voxelization patch, from `patch_index_of`
/// (voxelization patch → matrix patch); `usize::MAX` where none maps to it.
pub fn vox_of(patch_index_of: &[Option<u32>], n: usize) -> Vec<usize> {
    let mut out = vec![usize::MAX; n];
    for (v, m) in patch_index_of.iter().enumerate() {
        if let Some(m) = m {
            out[*m as usize] = v;
        }
    }
    out
}

/// From a point on a triangle to the triangle's piece holding it.
pub struct PieceLookup {
    /// Triangle `t`'s pieces are `vox.pieces[start[t]..start[t + 1]]`
    /// (sorted by voxel key).
    start: Vec<u32>,
}

impl PieceLookup {
    pub fn new(vox: &Voxelization, triangles: usize) -> PieceLookup {
        let mut start = vec![0u32; triangles + 1];
        for p in &vox.pieces {
            start[p.tri as usize + 1] += 1;
        }
        for t in 0..triangles {
            start[t + 1] += start[t];
        }
        PieceLookup { start }
    }

    /// The piece of triangle `t` holding world point `x`: the one in `x`'s
    /// voxel (of a cut piece, the part `x` lies in), else (rounding at a
    /// voxel boundary, a sliver below the voxelizer's threshold) the one
    /// whose voxel centre is nearest.
    pub fn find(&self, vox: &Voxelization, t: usize, x: [f64; 3]) -> Option<usize> {
        self.find_from(vox, t, x, [0.0; 3])
    }

    /// [`PieceLookup::find`], with the side of a cut tested at `x + back`
    /// (world): for a ray's hit, a step back towards its origin, so a hit
    /// at the foot of a wall counts on the side the ray came from.
    pub fn find_from(
        &self,
        vox: &Voxelization,
        t: usize,
        x: [f64; 3],
        back: [f64; 3],
    ) -> Option<usize> {
        let (a, b) = (self.start[t] as usize, self.start[t + 1] as usize);
        if a == b {
            return None;
        }
        let grid = &vox.grid;
        let g: [f64; 3] = std::array::from_fn(|k| (x[k] - grid.origin[k]) / grid.size);
        let v: [i64; 3] = g.map(|c| c.floor() as i64);
        // Of a cut piece (its parts in chain order), the part holding `x`:
        // along the chain while `x` is not on the positive side of a
        // part's own cut.
        let pick = |mut i: usize| -> usize {
            while i > a && vox.pieces[i].region.position() > 0 {
                i -= 1;
            }
            let p = vox.pieces[i].voxel;
            let local: [f64; 3] = std::array::from_fn(|k| g[k] + back[k] / grid.size - p[k] as f64);
            while i + 1 < b {
                match vox.pieces[i].region.own_cut() {
                    Some(cut) if cut.side(local) < 0.0 => i += 1,
                    _ => break,
                }
            }
            i
        };
        if (0..3).all(|k| v[k] >= 0 && v[k] < grid.dims[k] as i64) {
            let key = grid.key(v.map(|c| c as u32));
            let lo = a + vox.pieces[a..b].partition_point(|p| grid.key(p.voxel) < key);
            if lo < b && grid.key(vox.pieces[lo].voxel) == key {
                return Some(pick(lo));
            }
        }
        (a..b)
            .min_by(|&i, &j| {
                let d = |k: usize| {
                    (0..3)
                        .map(|q| (vox.pieces[k].voxel[q] as f64 + 0.5 - g[q]).powi(2))
                        .sum::<f64>()
                };
                d(i).total_cmp(&d(j))
            })
            .map(pick)
    }
}

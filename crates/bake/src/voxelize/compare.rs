//! Two voxelizations, or two lists of pieces, compared: how the OpenCL
//! path's f32 results differ from the f64 CPU reference (tests/voxelize.rs,
//! `bench voxelize`).

use super::{Piece, Voxelization, MIN_PIECE_AREA};
use radiosity_core::math::{dot, sub};
use radiosity_core::patch::Direction;
use serde::Serialize;
use std::collections::HashMap;

/// How two voxelizations of the same scene and grid differ (OpenCL against
/// the CPU reference).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Comparison {
    pub patches_a: usize,
    pub patches_b: usize,
    /// Patches (voxel, direction) present in only one of the two.
    pub only_in_a: usize,
    pub only_in_b: usize,
    /// Over the common patches: the largest albedo difference, and the
    /// largest area and centre differences in voxel units (area in voxel
    /// faces, centre in voxel edges).
    pub max_albedo_diff: f64,
    pub max_area_diff_faces: f64,
    pub max_centre_diff_voxels: f64,
}

/// Compares two voxelizations patch by patch, keyed by (voxel, direction).
pub fn compare(a: &Voxelization, b: &Voxelization) -> Comparison {
    let index = |v: &Voxelization| -> HashMap<(u64, Direction), usize> {
        v.patches
            .iter()
            .enumerate()
            .map(|(i, p)| ((v.grid.key(p.voxel), p.direction), i))
            .collect()
    };
    let (ia, ib) = (index(a), index(b));
    let mut c = Comparison {
        patches_a: a.patches.len(),
        patches_b: b.patches.len(),
        ..Default::default()
    };
    for (k, &i) in &ia {
        let Some(&j) = ib.get(k) else {
            c.only_in_a += 1;
            continue;
        };
        let (p, q) = (&a.patches[i], &b.patches[j]);
        for ch in 0..3 {
            c.max_albedo_diff = c.max_albedo_diff.max((p.albedo[ch] - q.albedo[ch]).abs());
        }
        let s2 = a.grid.size * a.grid.size;
        c.max_area_diff_faces = c.max_area_diff_faces.max((p.area - q.area).abs() / s2);
        let d = sub(p.centre, q.centre);
        c.max_centre_diff_voxels = c.max_centre_diff_voxels.max(dot(d, d).sqrt() / a.grid.size);
    }
    c.only_in_b = ib.keys().filter(|k| !ia.contains_key(k)).count();
    c
}

/// How the pieces of two paths (OpenCL f32 and CPU f64) differ on the same
/// grid. A triangle within rounding of a voxel boundary can graze a voxel in
/// one path and miss it in the other, or fall on different sides of
/// [`MIN_PIECE_AREA`]; every other piece must agree to f32 rounding.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PieceComparison {
    pub pieces_a: usize,
    pub pieces_b: usize,
    /// (triangle, voxel) pairs found by both.
    pub common: usize,
    /// Pairs found by only one path (grazing contacts).
    pub only_in_a: usize,
    pub only_in_b: usize,
    /// Largest area, in voxel faces, of a piece found by only one path.
    pub max_unmatched_area: f64,
    /// Common pieces kept (area > MIN_PIECE_AREA) by one path and not the other.
    pub threshold_crossings: usize,
    /// Largest area difference of a common piece, in voxel faces.
    pub max_area_diff: f64,
    /// Largest centroid difference of a common piece with area above
    /// 1e-3 faces, in voxel edges (tiny pieces have ill-conditioned centroids).
    pub max_centroid_diff: f64,
}

impl PieceComparison {
    /// Pieces whose outcome differs between the paths: the boundary cases.
    pub fn boundary_cases(&self) -> usize {
        self.only_in_a + self.only_in_b + self.threshold_crossings
    }
}

/// Compares two piece lists keyed by (triangle, voxel).
pub fn compare_pieces(a: &[Piece], b: &[Piece]) -> PieceComparison {
    let index: HashMap<(u32, [u32; 3]), usize> = b
        .iter()
        .enumerate()
        .map(|(i, p)| ((p.tri, p.voxel), i))
        .collect();
    let mut c = PieceComparison {
        pieces_a: a.len(),
        pieces_b: b.len(),
        ..Default::default()
    };
    let mut matched = vec![false; b.len()];
    for p in a {
        match index.get(&(p.tri, p.voxel)) {
            None => {
                c.only_in_a += 1;
                c.max_unmatched_area = c.max_unmatched_area.max(p.area);
            }
            Some(&j) => {
                matched[j] = true;
                c.common += 1;
                let q = &b[j];
                c.max_area_diff = c.max_area_diff.max((p.area - q.area).abs());
                if (p.area > MIN_PIECE_AREA) != (q.area > MIN_PIECE_AREA) {
                    c.threshold_crossings += 1;
                }
                if p.area > 1e-3 && q.area > 1e-3 {
                    let d = sub(p.centroid, q.centroid);
                    c.max_centroid_diff = c.max_centroid_diff.max(dot(d, d).sqrt());
                }
            }
        }
    }
    for (j, q) in b.iter().enumerate() {
        if !matched[j] {
            c.only_in_b += 1;
            c.max_unmatched_area = c.max_unmatched_area.max(q.area);
        }
    }
    c
}

//! Run-time emission: each patch's exitance `E` split by emissive material,
//! so that every material's `Ke` can be scaled or switched off per frame
//! (the `emission` map of the camera/lights file). The split is measured on
//! the patch's own triangle pieces (the surface map's), with the
//! voxelizer's weights: `E_j = Σ_m s_m Σ_{pieces k of m in j} A_k (n_k ·
//! N_j) Ke_m / A_j`, which at every scale `s_m = 1` is the patch's stored
//! emission.

use radiosity_bakefile::baked::Baked;
use radiosity_bakefile::surface::{NONE, PIECE_SUBSTITUTE};
use radiosity_core::math::{cross, dot, f64s, norm, sub};
use radiosity_core::patch::{piece_polygon, Grid};
use radiosity_core::scene::Scene;
use std::collections::BTreeMap;

/// Patches' emission per emissive material.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Emission {
    /// Emissive material names (the scene's), in material order.
    pub materials: Vec<String>,
    /// Per material: (patch in matrix order, exitance RGB at scale 1).
    pub parts: Vec<Vec<(u32, [f32; 3])>>,
}

impl Emission {
    /// The split for `baked`'s patches from `scene`'s emissive triangles.
    pub fn new(baked: &Baked, scene: &Scene) -> Emission {
        let map = &baked.surface_map;
        let grid = Grid {
            origin: map.origin,
            size: map.voxel_size,
            dims: map.dims,
        };
        let mut index: BTreeMap<usize, usize> = BTreeMap::new();
        let mut out = Emission::default();
        let mut sums: Vec<BTreeMap<u32, [f64; 3]>> = Vec::new();
        for t in 0..map.triangles().min(scene.triangles.len()) {
            let m = scene.triangle_material[t] as usize;
            let ke = scene.materials[m].emission;
            if ke.iter().all(|&e| e <= 0.0) {
                continue;
            }
            let slot = *index.entry(m).or_insert_with(|| {
                out.materials.push(scene.materials[m].name.clone());
                sums.push(BTreeMap::new());
                sums.len() - 1
            });
            let coords: [f64; 9] = std::array::from_fn(|k| {
                let v = scene.positions[scene.triangles[t][k / 3] as usize];
                grid.to_grid(v)[k % 3]
            });
            let nt = scene.triangle_normal(t);
            let first = map.tri_start[t] as usize;
            for (k, piece) in map.pieces_of(t).iter().enumerate() {
                if piece.patch == NONE || piece.flags & PIECE_SUBSTITUTE != 0 {
                    continue;
                }
                let poly = piece_polygon(
                    &grid,
                    &coords,
                    piece.voxel.map(u32::from),
                    &map.region(first + k),
                );
                let mut a2 = [0.0; 3];
                for i in 1..poly.len().saturating_sub(1) {
                    let c = cross(sub(poly[i], poly[0]), sub(poly[i + 1], poly[0]));
                    for k in 0..3 {
                        a2[k] += c[k];
                    }
                }
                let area = 0.5 * norm(a2);
                let p = &baked.patches[piece.patch as usize];
                let w = area * dot(nt, f64s(p.normal)) / p.area as f64;
                let e = sums[slot].entry(piece.patch).or_insert([0.0; 3]);
                for c in 0..3 {
                    e[c] += w * ke[c] as f64;
                }
            }
        }
        out.parts = sums
            .into_iter()
            .map(|s| {
                s.into_iter()
                    .map(|(p, e)| (p, e.map(|x| x.max(0.0) as f32)))
                    .collect()
            })
            .collect();
        out
    }

    /// `E` per patch (three channels, `n` each) with material scales
    /// `scales` (name → scale; unlisted materials 1).
    pub fn exitance(&self, n: usize, scales: &BTreeMap<String, f32>) -> [Vec<f32>; 3] {
        let mut e: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
        for (name, parts) in self.materials.iter().zip(&self.parts) {
            let s = scales.get(name).copied().unwrap_or(1.0);
            if s == 0.0 {
                continue;
            }
            for &(p, v) in parts {
                for c in 0..3 {
                    e[c][p as usize] += s * v[c];
                }
            }
        }
        e
    }
}

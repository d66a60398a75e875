//! What the phases of the reduction ([`super::reduce`]) share: a kept
//! piece's sort key, the sums of a group of pieces, and the geometry every
//! phase tests against. A leaf: the phases import it, it imports none of
//! them.

use super::Piece;
use radiosity_core::bvh::Bvh;
use radiosity_core::patch::{Direction, Grid};
use radiosity_core::scene::Scene;

/// A piece that takes part: (voxel key, facing direction, triangle, index
/// into the piece list). Sorted as a tuple, so pieces group by voxel, then
/// direction, then triangle.
pub(super) type Kept = (u64, Direction, u32, usize);

/// The scene and the structures every phase reads.
pub(super) struct Geometry<'a> {
    pub(super) scene: &'a Scene,
    pub(super) grid: &'a Grid,
    pub(super) bvh: &'a Bvh,
    /// Per triangle: its unit normal (f64, from the winding).
    pub(super) normals: &'a [[f64; 3]],
    /// [`super::CONNECT_LIFT`] and [`super::CONNECT_OWN`] in scene units.
    pub(super) lift: f64,
    pub(super) own: f64,
}

/// Sums of one voxel group, in f64.
#[derive(Clone, Copy, Default)]
pub(super) struct Acc {
    pub(super) area: f64,
    pub(super) moment: [f64; 3],
    pub(super) area_normal: [f64; 3],
    pub(super) albedo_normal: [[f64; 3]; 3],
    pub(super) emission_normal: [[f64; 3]; 3],
}

impl Acc {
    /// Adds `o`'s sums.
    pub(super) fn add(&mut self, o: &Acc) {
        self.area += o.area;
        for q in 0..3 {
            self.moment[q] += o.moment[q];
            self.area_normal[q] += o.area_normal[q];
            for c in 0..3 {
                self.albedo_normal[c][q] += o.albedo_normal[c][q];
                self.emission_normal[c][q] += o.emission_normal[c][q];
            }
        }
    }

    /// The sums of `share` of piece `p` of triangle `tri`.
    pub(super) fn of_piece(g: &Geometry, p: &Piece, tri: u32, share: f64) -> Acc {
        let (scene, grid) = (g.scene, g.grid);
        let s2 = grid.size * grid.size;
        let material = &scene.materials[scene.triangle_material[tri as usize] as usize];
        let n = g.normals[tri as usize];
        let a = p.area * s2 * share;
        let world: [f64; 3] = std::array::from_fn(|q| {
            grid.origin[q] + grid.size * (p.voxel[q] as f64 + p.centroid[q])
        });
        let mut acc = Acc {
            area: a,
            ..Default::default()
        };
        for q in 0..3 {
            acc.moment[q] = a * world[q];
            acc.area_normal[q] = a * n[q];
            for c in 0..3 {
                acc.albedo_normal[c][q] = a * n[q] * material.albedo[c] as f64;
                acc.emission_normal[c][q] = a * n[q] * material.emission[c] as f64;
            }
        }
        acc
    }
}

//! Facing: a bake whose surfaces see nothing is never a success. After the
//! form factors, the share of the patch area that sees no other surface
//! from its front (patches removed for seeing nothing) is measured; when
//! no patch is left, or more than [`BLIND_LIMIT`] of the area is blind,
//! rays are cast from the patches' **back** sides: if most of them meet
//! the backs of other surfaces, the scene is closed on the side the faces
//! point away from — the faces are wound away from each other (outward
//! normals, a common export of closed models) — and the bake stops with
//! that cause and its remedies. A scene that is merely open (one plane, a
//! few objects under the sky) keeps its blind patches and bakes, unless
//! nothing at all is left.
//!
//! With two-sided surfaces (`Scene::with_back_sides`) half the patches of a
//! closed model face away from it by construction, so only `n = 0` stops
//! the bake.
//!
//! **Some faces reversed.** A scene wound mostly right but with some faces
//! the wrong way (one wall of a room flipped, a mirrored object) bakes,
//! but the flipped faces see nothing from their front, lose their patches
//! and reflect no light: a wall of the room stays dark. So whenever some
//! patch area is blind, the blind patches' back sides are probed too; a
//! blind patch more than [`REVERSED_FRONT_SHARE`] of whose back-side rays
//! meet the *front* of another surface faces away from a scene that looks
//! at it, and when such patches make up more than [`REVERSED_WARN_SHARE`]
//! of the area the bake warns, naming the materials with the most of that
//! area and the remedies. Blind patches made of faces that have a back
//! side (`bake::winding` gave them one) are not counted: their back side
//! is the patch that sees the scene. Blind faces that face the sky in an
//! open scene (a roof, the top of a box) see backs or nothing behind them
//! and are not counted.

use crate::cover::{fan_direction, COVER_LIFT, ENCLOSED_RAYS};
use crate::error::BakeError;
use crate::form_factor::FormFactors;
use crate::voxelize::Voxelization;
use radiosity_core::bvh::Bvh;
use radiosity_core::math::dot;
use radiosity_core::scene::Scene;
use serde::Serialize;

/// Blind patch area above this share of the whole triggers the back-side
/// probe.
pub const BLIND_LIMIT: f64 = 0.5;

/// Back-side rays meeting back faces above this share mean inverted
/// winding.
pub const INVERTED_LIMIT: f64 = 0.5;

/// A blind patch is counted as reversed when more than this share of its
/// back-side rays meet the front of another surface (module doc). A wall
/// flipped in an otherwise right box sees fronts with about half of its
/// fan (the rest meets other flipped walls' backs, or all fronts when it is
/// the only one flipped); a box top under the sky sees only backs.
pub const REVERSED_FRONT_SHARE: f64 = 0.25;

/// Reversed patch area above this share of the whole is warned about.
pub const REVERSED_WARN_SHARE: f64 = 0.01;

/// Rays per patch of the back-side probe: the direction opposite the normal
/// and the enclosure test's fan around it ([`fan_direction`]).
const PROBE_RAYS: usize = ENCLOSED_RAYS;

/// What the facing check measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Facing {
    /// Share of the voxelization's patch area that sees nothing.
    pub blind_area_share: f64,
    /// Back-side probe (run only when the blind share is large): rays cast
    /// and the share that met the back of another surface first.
    pub probe_rays: u64,
    pub probe_back_share: f64,
    /// Blind patches whose back sides see the fronts of other surfaces
    /// (module doc, "Some faces reversed"): count and share of the area.
    pub reversed_patches: u64,
    pub reversed_area_share: f64,
    /// What the bake should tell the user (empty when all is well).
    pub warnings: Vec<String>,
}

/// The check (module doc). `two_sided`: the scene has back sides.
pub fn check(
    scene: &Scene,
    vox: &Voxelization,
    ff: &FormFactors,
    two_sided: bool,
) -> Result<Facing, BakeError> {
    let total: f64 = vox.patches.iter().map(|p| p.area).sum();
    let kept: f64 = ff.kept.iter().map(|&i| vox.patches[i].area).sum();
    let mut facing = Facing {
        blind_area_share: if total > 0.0 { 1.0 - kept / total } else { 1.0 },
        ..Facing::default()
    };
    if !two_sided && (ff.n == 0 || facing.blind_area_share > BLIND_LIMIT) {
        let all: Vec<usize> = (0..vox.patches.len()).collect();
        let (rays, back) = probe(scene, vox, &all)
            .iter()
            .fold((0, 0), |a, h| (a.0 + PROBE_RAYS as u64, a.1 + h.back));
        facing.probe_rays = rays;
        facing.probe_back_share = if rays > 0 {
            back as f64 / rays as f64
        } else {
            0.0
        };
        if facing.probe_back_share > INVERTED_LIMIT {
            return Err(BakeError::Facing {
                detail: format!(
                    "{:.0} % of the surface area sees no other surface from its front, while \
                     {:.0} % of the rays leaving the surfaces' back sides meet the backs of other \
                     surfaces: the faces are most likely wound away from each other (normals \
                     pointing out of closed models, a common export). Re-export the scene with \
                     its faces towards the viewer (counter-clockwise seen from the lit side), \
                     or bake two-sided (patches on both sides of every surface)",
                    100.0 * facing.blind_area_share,
                    100.0 * facing.probe_back_share
                ),
            });
        }
    }
    if ff.n == 0 {
        return Err(BakeError::Facing {
            detail: format!(
                "no patch sees another surface ({} patches of voxels {:.4e} wide, {} × {} × {} \
                 across the scene, all removed): there is nothing to bake, as no light can \
                 bounce between surfaces. A closed or at least partly enclosing scene is \
                 needed, with its parts larger than a voxel (surfaces closer than a voxel merge \
                 into one patch, so a large ground plane around a small building leaves the \
                 building inside a voxel: crop the ground or bake more patches){}",
                vox.patches.len(),
                vox.grid.size,
                vox.grid.dims[0],
                vox.grid.dims[1],
                vox.grid.dims[2],
                if two_sided {
                    ""
                } else {
                    "; if the faces' winding is unreliable, bake two-sided"
                }
            ),
        });
    }
    if !two_sided && facing.blind_area_share > 0.0 {
        reversed(scene, vox, ff, total, &mut facing);
    }
    Ok(facing)
}

/// The "some faces reversed" measure and warning (module doc).
fn reversed(scene: &Scene, vox: &Voxelization, ff: &FormFactors, total: f64, facing: &mut Facing) {
    let mut kept = vec![false; vox.patches.len()];
    for &i in &ff.kept {
        kept[i] = true;
    }
    // Patches whose every piece has a back side (the winding check gave
    // it one: `Scene::twin`) are the outward halves of faces already
    // turned towards the scene: not reversed.
    let mut has_back = vec![true; vox.patches.len()];
    for piece in &vox.pieces {
        if let Some(p) = piece.patch {
            if scene.twin(piece.tri as usize).is_none() {
                has_back[p as usize] = false;
            }
        }
    }
    let blind: Vec<usize> = (0..vox.patches.len())
        .filter(|&i| !kept[i] && !has_back[i])
        .collect();
    let hits = probe(scene, vox, &blind);
    let mut is_reversed = vec![false; vox.patches.len()];
    let mut area = 0.0;
    for (&i, h) in blind.iter().zip(&hits) {
        if h.front as f64 > REVERSED_FRONT_SHARE * PROBE_RAYS as f64 {
            is_reversed[i] = true;
            facing.reversed_patches += 1;
            area += vox.patches[i].area;
        }
    }
    facing.reversed_area_share = if total > 0.0 { area / total } else { 0.0 };
    if facing.reversed_area_share <= REVERSED_WARN_SHARE {
        return;
    }
    // The materials with the most reversed area: each reversed patch's
    // area shared equally among its pieces' materials.
    let mut pieces_of = vec![0u32; vox.patches.len()];
    for p in vox.pieces.iter().filter_map(|piece| piece.patch) {
        pieces_of[p as usize] += 1;
    }
    let mut by_material = vec![0.0f64; scene.materials.len()];
    for piece in &vox.pieces {
        if let Some(p) = piece.patch.map(|p| p as usize) {
            if is_reversed[p] {
                let m = scene.triangle_material[piece.tri as usize] as usize;
                by_material[m] += vox.patches[p].area / f64::from(pieces_of[p]);
            }
        }
    }
    let mut order: Vec<usize> = (0..by_material.len())
        .filter(|&m| by_material[m] > 0.0)
        .collect();
    order.sort_by(|&a, &b| by_material[b].total_cmp(&by_material[a]).then(a.cmp(&b)));
    let names: Vec<String> = order
        .iter()
        .take(3)
        .map(|&m| format!("`{}`", scene.materials[m].name))
        .collect();
    facing.warnings.push(format!(
        "{} patches ({:.1} % of the surface area) see nothing from their front while their \
         back sides see the fronts of other surfaces: their faces are most likely wound the \
         wrong way (materials {}{}), so they were removed and reflect no light. Re-export \
         those faces towards the viewer (counter-clockwise seen from the lit side), or bake \
         two-sided (patches on both sides of every surface)",
        facing.reversed_patches,
        100.0 * facing.reversed_area_share,
        names.join(", "),
        if order.len() > 3 {
            format!(" and {} more", order.len() - 3)
        } else {
            String::new()
        }
    ));
}

/// What one patch's back-side rays met first.
#[derive(Clone, Copy, Default)]
struct BackHits {
    /// The back of a surface.
    back: u64,
    /// The front of a surface.
    front: u64,
}

/// [`PROBE_RAYS`] rays from the centres of the patches `which` into their
/// back hemispheres: per patch, what they met first.
fn probe(scene: &Scene, vox: &Voxelization, which: &[usize]) -> Vec<BackHits> {
    use rayon::prelude::*;
    let shift = crate::form_factor::shift_of(&vox.grid);
    let bvh = Bvh::build(&scene.positions, &scene.triangles, shift);
    let normals = scene.triangle_normals();
    let (lo, hi) = scene.bounds();
    let diagonal = (0..3)
        .map(|q| ((hi[q] - lo[q]) as f64).powi(2))
        .sum::<f64>()
        .sqrt()
        .max(1e-30);
    let lift = COVER_LIFT * vox.grid.size;
    let reach = 2.0 * diagonal + vox.grid.size;
    which
        .par_iter()
        .map(|&i| {
            let p = &vox.patches[i];
            let b = p.normal.map(|v| -v);
            let o: [f64; 3] = std::array::from_fn(|q| p.centre[q] + lift * b[q] - shift[q]);
            let mut hits = BackHits::default();
            for k in 0..PROBE_RAYS {
                let d = fan_direction(b, k, PROBE_RAYS);
                if let Some((leaf, _)) = bvh.closest_hit(o, d.map(|v| v * reach)) {
                    let tri = bvh.order[leaf as usize] as usize;
                    if dot(normals[tri], d) > 0.0 {
                        hits.back += 1;
                    } else {
                        hits.front += 1;
                    }
                }
            }
            hits
        })
        .collect()
}

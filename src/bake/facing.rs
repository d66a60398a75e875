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

use crate::bake::cover::{fan_direction, COVER_LIFT, ENCLOSED_RAYS};
use crate::bake::error::BakeError;
use crate::bake::form_factor::FormFactors;
use crate::bake::voxelize::Voxelization;
use crate::core::bvh::Bvh;
use crate::core::math::dot;
use crate::core::scene::Scene;
use serde::Serialize;

/// Blind patch area above this share of the whole triggers the back-side
/// probe.
pub const BLIND_LIMIT: f64 = 0.5;

/// Back-side rays meeting back faces above this share mean inverted
/// winding.
pub const INVERTED_LIMIT: f64 = 0.5;

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
        let (rays, back) = probe(scene, vox);
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
                "no patch sees another surface ({} patches, all removed): there is nothing to \
                 bake, as no light can bounce between surfaces. A closed or at least partly \
                 enclosing scene is needed{}",
                vox.patches.len(),
                if two_sided {
                    ""
                } else {
                    "; if the faces' winding is unreliable, bake two-sided"
                }
            ),
        });
    }
    Ok(facing)
}

/// Rays from every patch's centre into its back hemisphere: (rays cast,
/// rays whose first hit is the back of a surface).
fn probe(scene: &Scene, vox: &Voxelization) -> (u64, u64) {
    use rayon::prelude::*;
    let shift = crate::bake::form_factor::shift_of(&vox.grid);
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
    vox.patches
        .par_iter()
        .map(|p| {
            let b = p.normal.map(|v| -v);
            let o: [f64; 3] = std::array::from_fn(|q| p.centre[q] + lift * b[q] - shift[q]);
            let mut back = 0u64;
            for k in 0..PROBE_RAYS {
                let d = fan_direction(b, k, PROBE_RAYS);
                if let Some((leaf, _)) = bvh.closest_hit(o, d.map(|v| v * reach)) {
                    let tri = bvh.order[leaf as usize] as usize;
                    if dot(normals[tri], d) > 0.0 {
                        back += 1;
                    }
                }
            }
            (PROBE_RAYS as u64, back)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

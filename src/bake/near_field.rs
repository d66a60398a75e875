//! Bake stage: the near-field correction ([`crate::bakefile::near_field`]
//! says what it is and how the run time applies it).
//!
//! From each patch's [`SAMPLES_PER_PATCH`] sample points (on its real
//! pieces, where the run time lights it), `rays / 16` cosine-distributed
//! rays each, directions from the last two coordinates of the form
//! factors' quasi-random sequence with a seeded rotation per patch
//! (deterministic). The nearest front face a ray meets is credited, as in
//! the form factors ([`crate::bake::form_factor::rays`]), to the patch
//! owning the hit piece — and within it to the cell of the sample point
//! nearest the hit. Links whose measured form factor is below
//! [`MIN_FORM_FACTOR`] are dropped.
//!
//! Noise: a link's cells hold about `F̂_ij · rays / 16` rays each; at the
//! default 4,096 rays and `F̂ = 0.1`, about 26, so a cell's weight has a
//! relative noise near 20 %. The correction uses only each cell's
//! deviation from the link's mean, and on Sponza at 4.5k patches 8,192
//! rays instead of 4,096 moved the red channel's `H` error by about a
//! percent (`docs/accuracy.md`).

use super::error::BakeError;
use super::form_factor::rays::{cosine_direction, geo_normal, R4};
use super::form_factor::shift_of;
use super::pieces::PieceLookup;
use super::voxelize::{Cover, Voxelization};
use crate::bakefile::near_field::{NearField, NearLink, MIN_FORM_FACTOR};
use crate::bakefile::surface::{PatchSamples, SAMPLES_PER_PATCH};
use crate::core::bvh::Bvh;
use crate::core::math::{add, dot, scale, sub, SplitMix64};
use crate::core::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Instant;

/// Rays per patch by default (module doc).
pub const DEFAULT_RAYS: u32 = 4096;

/// Most rays per patch: the counts are `u16`, and the rays are rounded up
/// to a multiple of 16 (one share per sample point).
pub const MAX_RAYS: u32 = 65_520;

/// What the stage did, for the bake report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NearFieldStats {
    pub rays_per_patch: u32,
    pub links: u64,
    pub links_per_patch: f64,
    pub bytes: u64,
    pub seconds: f64,
}

/// The correction for the `n` patches in matrix order (`patch_index_of`:
/// voxelization patch → matrix patch), whose sample points are `samples`
/// (matrix order); `rays` per patch (0: none).
pub fn build(
    scene: &Scene,
    vox: &Voxelization,
    patch_index_of: &[Option<u32>],
    samples: &PatchSamples,
    n: usize,
    rays: u32,
) -> Result<(NearField, NearFieldStats), BakeError> {
    let start = Instant::now();
    if rays == 0 || n == 0 {
        return Ok((NearField::none(), NearFieldStats::default()));
    }
    if rays > MAX_RAYS {
        return Err(BakeError::InvalidOption {
            option: "near-field rays per patch",
            value: rays.to_string(),
            expected: format!("0..={MAX_RAYS}"),
        });
    }
    let per_point = (rays as usize).div_ceil(SAMPLES_PER_PATCH);
    let cast = (per_point * SAMPLES_PER_PATCH) as u32;
    let lookup = PieceLookup::new(vox, scene.triangles.len());
    let shift = shift_of(&vox.grid);
    let bvh = Bvh::build(&scene.positions, &scene.triangles, shift);
    let normals: Vec<[f64; 3]> = scene.triangle_normals();
    let cover = Cover::new(scene, &vox.grid, &bvh, &normals);
    let (lo, hi) = scene.bounds();
    let extent = (0..3)
        .map(|a| (hi[a] - lo[a]) as f64)
        .fold(0.0, f64::max)
        .max(1e-30);
    let offset = 1e-4 * extent;
    let far = 4.0 * extent;
    let point = |s: usize| samples.position[s].map(f64::from);
    let rows: Vec<Vec<NearLink>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut rng = SplitMix64::new(
                0x5851_f42d_4c95_7f2d ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15),
            );
            let rot: [f64; 2] = std::array::from_fn(|_| rng.uniform());
            let mut links: BTreeMap<u32, [u16; SAMPLES_PER_PATCH]> = BTreeMap::new();
            for k in 0..SAMPLES_PER_PATCH {
                let s = i * SAMPLES_PER_PATCH + k;
                let (x, nrm) = (point(s), samples.normal[s].map(f64::from));
                for r in 0..per_point {
                    let q = (k * per_point + r) as f64;
                    let u1 = (rot[0] + R4[2] * q).fract();
                    let u2 = (rot[1] + R4[3] * q).fract();
                    let d = cosine_direction(nrm, u1, u2);
                    let o = sub(add(x, scale(nrm, offset)), shift);
                    let Some((mut leaf, tp)) = bvh.closest_hit(o, scale(d, far)) else {
                        continue;
                    };
                    if dot(geo_normal(&bvh, leaf), d) >= 0.0 {
                        match cover.front_at(o, d, tp * far, u32::MAX) {
                            Some(front) => leaf = front,
                            None => continue,
                        }
                    }
                    let tri = bvh.order[leaf as usize] as usize;
                    let y = add(add(o, scale(d, tp * far)), shift);
                    let Some(j) = lookup
                        .find(vox, tri, y)
                        .and_then(|p| vox.pieces[p].patch)
                        .and_then(|v| patch_index_of[v as usize])
                    else {
                        continue;
                    };
                    if j as usize == i {
                        continue;
                    }
                    let base = j as usize * SAMPLES_PER_PATCH;
                    let cell = (0..SAMPLES_PER_PATCH)
                        .min_by(|&a, &b| {
                            let d2 = |c: usize| {
                                let p = point(base + c);
                                (0..3).map(|q| (p[q] - y[q]).powi(2)).sum::<f64>()
                            };
                            d2(a).total_cmp(&d2(b))
                        })
                        .expect("16 cells");
                    let e = links.entry(j).or_insert([0; SAMPLES_PER_PATCH]);
                    e[cell] = e[cell].saturating_add(1);
                }
            }
            let min = (MIN_FORM_FACTOR * cast as f64).ceil() as u64;
            links
                .into_iter()
                .filter(|(_, c)| c.iter().map(|&v| v as u64).sum::<u64>() >= min)
                .map(|(patch, counts)| NearLink { patch, counts })
                .collect()
        })
        .collect();
    let mut nf = NearField {
        rays: cast,
        starts: Vec::with_capacity(n + 1),
        links: Vec::new(),
    };
    nf.starts.push(0);
    for r in rows {
        nf.links.extend(r);
        nf.starts.push(nf.links.len() as u32);
    }
    let stats = NearFieldStats {
        rays_per_patch: cast,
        links: nf.links.len() as u64,
        links_per_patch: nf.links.len() as f64 / n as f64,
        bytes: nf.to_bytes().len() as u64,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((nf, stats))
}

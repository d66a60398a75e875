//! Bake stage: the near-field correction ([`radiosity_bakefile::near_field`]
//! says what it is and how the run time applies it).
//!
//! From each patch, `rays` cosine-distributed rays leave points spread
//! over its real pieces by area, exactly as the form factors' rays do
//! ([`crate::form_factor::rays`], with another rotation of the
//! quasi-random sequence; deterministic): `H_i` is the mean over the
//! patch's whole region, so its correction is too (rays from the 16 sample
//! points instead favour the pieces they sit on — the outermost — and on
//! Sponza's camera view that made the image worse while the patch measure,
//! taken at the same points, improved). The nearest front face a ray meets
//! is credited to the patch owning the hit piece, and within it to the cell
//! of the sample point nearest the hit. Origins on the covered part of a
//! partly covered piece are not cast, and a receiver's counts are scaled to
//! `rays` cast. Links whose measured form factor is below
//! `min_form_factor` ([`MIN_FORM_FACTOR`] by default) are dropped, and
//! their rays, weighted by the receiver's area per ray traced (as the form
//! factors' rays weigh theirs, so that `A_i F̂_ij = A_j F̂_ji` holds on
//! average), make up each neighbour's far weights. The same rays, counted
//! by the cell of the receiver's own point nearest their origin, give each
//! cell's open sky: the share of its rays that leave the scene
//! (`NearField::sky`; about 256 rays a cell at the default, so a binomial
//! error near 0.03 — `tests/sky_near_field.rs` checks it against the exact
//! view factor to an opening).
//!
//! Noise: a link's cells hold about `F̂_ij · rays / 16` rays each; at the
//! default 4,096 rays and `F̂ = 0.1`, about 26, so a cell's weight has a
//! relative noise near 20 %. The correction uses only each cell's
//! deviation from the link's mean, and on Sponza at 4.5k patches 8,192
//! rays instead of 4,096 moved the red channel's `H` error by about a
//! percent (`docs/accuracy.md`).

use super::compute::Backend;
use super::error::BakeError;
use super::form_factor::batches::{trace_rows, Ray};
use super::form_factor::rays::{cosine_direction, Origins};
use super::form_factor::tracer::{device_tracer, with_tracer, Hit};
use super::form_factor::RayDevice;
use super::pieces;
use super::voxelize::Voxelization;
use radiosity_bakefile::near_field::{face_coords, receiver_cell, NearField, NearLink};
use radiosity_bakefile::surface::{PatchSamples, SAMPLES_PER_PATCH};
use radiosity_core::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Instant;

/// Rays per patch by default (module doc).
pub const DEFAULT_RAYS: u32 = 4096;

pub use radiosity_bakefile::near_field::MIN_FORM_FACTOR;

/// Points per patch measuring its cells' area shares: a share's standard
/// error is at most `√(s(1 − s)/N)`, 0.8 % of the area for a 1/16 cell.
const SHARE_POINTS: usize = 1024;

/// Most rays per patch: the counts are `u16`.
pub const MAX_RAYS: u32 = 65_535;

/// What the stage did, for the bake report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NearFieldStats {
    pub rays_per_patch: u32,
    /// Links below this measured form factor were dropped.
    pub min_form_factor: f64,
    pub links: u64,
    pub links_per_patch: f64,
    pub bytes: u64,
    pub seconds: f64,
}

/// Checks the stage's options: `rays` per patch at most [`MAX_RAYS`], the
/// minimum form factor of a stored link in 0..=1 (the bake's config checks
/// them with this before any work).
pub fn check_options(rays: u32, min_form_factor: f64) -> Result<(), BakeError> {
    if rays > MAX_RAYS {
        return Err(BakeError::InvalidOption {
            option: "near-field rays per patch",
            value: rays.to_string(),
            expected: format!("0..={MAX_RAYS}"),
        });
    }
    if !(0.0..=1.0).contains(&min_form_factor) {
        return Err(BakeError::InvalidOption {
            option: "near-field minimum form factor",
            value: min_form_factor.to_string(),
            expected: "a number in 0..=1".into(),
        });
    }
    Ok(())
}

/// The correction for the `n` patches in matrix order (`patch_index_of`:
/// voxelization patch → matrix patch), whose sample points are `samples`
/// (matrix order); `rays` per patch (0: none), links with a measured form
/// factor of at least `min_form_factor` stored. The rays are traced on
/// `backend`'s device as `ray_device` says (the form factors' rule,
/// [`crate::form_factor::rays::form_factors`]): the same links either way.
/// `progress(done, total)` counts receivers.
// The inputs are separate products of earlier stages and the bake's
// options; a struct bundling them would exist for this call alone.
#[allow(clippy::too_many_arguments)]
pub fn build(
    scene: &Scene,
    vox: &Voxelization,
    patch_index_of: &[Option<u32>],
    samples: &PatchSamples,
    n: usize,
    rays: u32,
    min_form_factor: f64,
    backend: &Backend,
    ray_device: RayDevice,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(NearField, NearFieldStats), BakeError> {
    let start = Instant::now();
    if rays == 0 || n == 0 {
        return Ok((NearField::none(), NearFieldStats::default()));
    }
    check_options(rays, min_form_factor)?;
    let cast = rays;
    let vox_of = pieces::vox_of(patch_index_of, n);
    let (shares, stored, far_sum, sky, cell_rays) =
        with_tracer(scene, vox, |tracer, geo, by_patch| {
            let point = |s: usize| samples.position[s].map(f64::from);
            // The first of the nearest sample points (each distance
            // computed once, in a loop the compiler keeps inline: as a
            // `min_by` over closures it computed each twice, and a change
            // elsewhere in the crate once left it a call per comparison,
            // the near-field stage 1.2× slower).
            let nearest = |j: usize, y: [f64; 3]| -> usize {
                let base = j * SAMPLES_PER_PATCH;
                let mut best = (f64::INFINITY, 0usize);
                for c in 0..SAMPLES_PER_PATCH {
                    let p = point(base + c);
                    let d2 = (p[0] - y[0]).powi(2) + (p[1] - y[1]).powi(2) + (p[2] - y[2]).powi(2);
                    if d2 < best.0 {
                        best = (d2, c);
                    }
                }
                best.1
            };
            // Each patch's cell shares: SHARE_POINTS points over its visible
            // pieces by area, each to its nearest sample point.
            let shares: Vec<[f32; SAMPLES_PER_PATCH]> = (0..n)
                .into_par_iter()
                .map(|j| {
                    let v = vox_of[j];
                    let uniform = [1.0 / SAMPLES_PER_PATCH as f32; SAMPLES_PER_PATCH];
                    if v == usize::MAX {
                        return uniform;
                    }
                    let origins =
                        Origins::of_patch(v, &by_patch[v], geo, vox, 0x2545_f491_4f6c_dd1d);
                    if origins.is_empty() {
                        return uniform;
                    }
                    let mut c = [0u32; SAMPLES_PER_PATCH];
                    let mut f = 0usize;
                    for k in 0..SHARE_POINTS {
                        let (x, nrm, partial, _) = origins.point(k, SHARE_POINTS, &mut f);
                        if !partial.is_some_and(|tri| tracer.cover.covered(x, nrm, tri)) {
                            c[nearest(j, x)] += 1;
                        }
                    }
                    let total: u32 = c.iter().sum();
                    if total == 0 {
                        return uniform;
                    }
                    let s: [f64; SAMPLES_PER_PATCH] =
                        std::array::from_fn(|k| c[k] as f64 / total as f64);
                    s.map(|v| v as f32)
                })
                .collect();
            // Per receiver: its stored links, its area per ray traced, its
            // dropped links' ray counts (for the far weights), and per cell of its
            // own the rays cast from origins nearest that cell's point and those of
            // them that left the scene (its open sky, `NearField::sky`).
            type Row = (
                Vec<NearLink>,
                f64,
                Vec<(u32, [u16; SAMPLES_PER_PATCH])>,
                [[u32; SAMPLES_PER_PATCH]; 3],
            );
            // A receiver's rays (None: it casts none), and how many of its
            // origins were covered.
            let draw = |i: usize, out: &mut Vec<Ray>| -> Option<u32> {
                let v = vox_of[i];
                if v == usize::MAX {
                    return None;
                }
                let origins = Origins::of_patch(v, &by_patch[v], geo, vox, 0x5851_f42d_4c95_7f2d);
                if origins.is_empty() {
                    return None;
                }
                let (mut f, mut covered) = (0usize, 0u32);
                for k in 0..rays as usize {
                    let (x, nrm, partial, r) = origins.point(k, rays as usize, &mut f);
                    if partial.is_some_and(|tri| tracer.cover.covered(x, nrm, tri)) {
                        covered += 1;
                        continue;
                    }
                    out.push(Ray {
                        x,
                        n: nrm,
                        d: cosine_direction(nrm, r[2], r[3]),
                    });
                }
                Some(covered)
            };
            let row_of = |i: usize, covered: Option<u32>, drawn: &[Ray], hits: &[Hit]| -> Row {
                let Some(covered) = covered else {
                    return Row::default();
                };
                let v = vox_of[i];
                // Per neighbour: its rays by the neighbour's cell they meet, and
                // by the receiver's cell they leave.
                type Counts = ([u32; SAMPLES_PER_PATCH], [u32; SAMPLES_PER_PATCH]);
                let mut links: BTreeMap<u32, Counts> = BTreeMap::new();
                let mut open = [[0u32; SAMPLES_PER_PATCH]; 3];
                for (ray, hit) in drawn.iter().zip(hits) {
                    let x = ray.x;
                    let own = nearest(i, x);
                    open[0][own] += 1;
                    // The receiver's face cell (the bakefile's "At the
                    // receiver").
                    let g: [f64; 3] =
                        std::array::from_fn(|a| (x[a] - vox.grid.origin[a]) / vox.grid.size);
                    let patch = &vox.patches[v];
                    let (fu, fv) = face_coords(g, patch.voxel, patch.direction.axis());
                    let face = receiver_cell(fu, fv);
                    open[2][face] += 1;
                    let (patch, y) = match *hit {
                        Hit::Owned { patch, y, .. } => (patch, y),
                        Hit::Escaped => {
                            open[1][own] += 1;
                            continue;
                        }
                        _ => continue,
                    };
                    let Some(j) = patch_index_of[patch as usize] else {
                        continue;
                    };
                    if j as usize == i {
                        continue;
                    }
                    let cell = nearest(j as usize, y);
                    let e = links
                        .entry(j)
                        .or_insert(([0; SAMPLES_PER_PATCH], [0; SAMPLES_PER_PATCH]));
                    e.0[cell] += 1;
                    e.1[face] += 1;
                }
                // Counts per ray cast, in units of `rays` (rounded down, so a
                // receiver's counts never exceed `rays`).
                let done = rays.saturating_sub(covered);
                if done == 0 {
                    return Row::default();
                }
                let to_rays = rays as f64 / done as f64;
                let mut row: Row = (
                    Vec::new(),
                    vox.patches[v].area / done as f64,
                    Vec::new(),
                    open,
                );
                let min = min_form_factor * rays as f64;
                for (patch, (c, from)) in links {
                    let counts: [u16; SAMPLES_PER_PATCH] =
                        std::array::from_fn(|k| (c[k] as f64 * to_rays).floor() as u16);
                    if counts.iter().map(|&v| v as f64).sum::<f64>() >= min {
                        // Raw counts by the receiver's cell: at most its rays
                        // cast from that cell.
                        let from = from.map(|v| v as u16);
                        row.0.push(NearLink {
                            patch,
                            counts,
                            from,
                        });
                    } else {
                        // Raw counts: at most `rays` ≤ MAX_RAYS each.
                        row.2.push((patch, c.map(|v| v as u16)));
                    }
                }
                row
            };
            // Receivers in chunks (`trace_rows` hands them over a chunk at a
            // time), so that the dropped links' counts (up to one
            // list entry per neighbour a receiver's rays meet: thousands at large
            // patch counts) are folded into the far sums and freed as they come.
            let mut stored: Vec<Vec<NearLink>> = Vec::with_capacity(n);
            let mut far_sum = vec![[0.0f64; SAMPLES_PER_PATCH]; n];
            let mut sky: Vec<[f32; SAMPLES_PER_PATCH]> = Vec::with_capacity(n);
            let mut cast_of: Vec<[u16; SAMPLES_PER_PATCH]> = Vec::with_capacity(n);
            let (mut device, _) = device_tracer(backend, tracer.rays, ray_device)?;
            trace_rows(
                tracer,
                device.as_mut(),
                n,
                rays as usize,
                draw,
                row_of,
                &mut |_, (links, per_ray, dropped, [cast, open, face]): Row| {
                    sky.push(open_fractions(&cast, &open));
                    cast_of.push(face.map(|v| v as u16));
                    for (j, c) in dropped {
                        for (f, &v) in far_sum[j as usize].iter_mut().zip(&c) {
                            *f += v as f64 * per_ray;
                        }
                    }
                    stored.push(links);
                },
                progress,
            )?;
            Ok::<_, BakeError>((shares, stored, far_sum, sky, cast_of))
        })?;

    // Far weights: the dropped rays per neighbour cell, normalised; a patch
    // none of them meets takes its area shares.
    let far: Vec<[f32; SAMPLES_PER_PATCH]> = far_sum
        .iter()
        .zip(&shares)
        .map(|(f, s)| {
            let total: f64 = f.iter().sum();
            if total > 0.0 {
                f.map(|v| (v / total) as f32)
            } else {
                *s
            }
        })
        .collect();
    let mut nf = NearField {
        rays: cast,
        starts: Vec::with_capacity(n + 1),
        links: Vec::new(),
        shares,
        far,
        sky,
        cast: cell_rays,
    };
    nf.starts.push(0);
    for r in stored {
        nf.links.extend(r);
        nf.starts.push(nf.links.len() as u32);
    }
    let stats = NearFieldStats {
        rays_per_patch: cast,
        min_form_factor,
        links: nf.links.len() as u64,
        links_per_patch: nf.links.len() as f64 / n as f64,
        bytes: nf.to_bytes().len() as u64,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((nf, stats))
}

/// A patch's open sky per cell (`NearField::sky`): the rays that left the
/// scene over those cast from each cell's origins; a cell no origin fell
/// in takes the patch's fraction (0 for a patch with no ray cast).
fn open_fractions(
    cast: &[u32; SAMPLES_PER_PATCH],
    open: &[u32; SAMPLES_PER_PATCH],
) -> [f32; SAMPLES_PER_PATCH] {
    let (c, o) = (
        cast.iter().map(|&v| u64::from(v)).sum::<u64>(),
        open.iter().map(|&v| u64::from(v)).sum::<u64>(),
    );
    let patch = if c == 0 { 0.0 } else { o as f64 / c as f64 };
    std::array::from_fn(|k| {
        if cast[k] == 0 {
            patch as f32
        } else {
            (f64::from(open[k]) / f64::from(cast[k])) as f32
        }
    })
}

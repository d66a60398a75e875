//! Direct light on patches per frame (DESIGN.md run time step 2): `D_j` is
//! the mean irradiance over the patch's sample points on its real triangle
//! pieces ([`crate::bakefile::surface`]), each shadowed by a ray against the
//! original triangles ([`crate::core::direct::DirectLight::at_points_each`],
//! which tries each light's last blocker among a patch's points before the
//! BVH; the one definition of each light is in [`crate::core::light`]). The first
//! [`DEFAULT_SAMPLES`] of the 16 stored points are used by default: a patch
//! half in shadow then gets 4/8 of the light, within 1/8; the points are in
//! a progressive order, so any count is spread over the patch. `B0 = ρ ∘ D
//! + E`.

use crate::bakefile::baked::Baked;
use crate::bakefile::surface::SAMPLES_PER_PATCH;
use crate::core::direct::DirectLight;
use crate::core::light::Prepared;
use crate::core::scene_config::Light;
use rayon::prelude::*;

/// Sample points per patch used by default (module doc).
pub const DEFAULT_SAMPLES: usize = 8;

/// `D` (three channels, `n` each) on every patch of `baked` from `lights`,
/// from the first `samples` points of each patch (1..=16).
pub fn patch_irradiance(
    baked: &Baked,
    dl: &DirectLight,
    lights: &[Light],
    samples: usize,
) -> [Vec<f32>; 3] {
    irradiance(baked, dl, lights, samples).1
}

/// The direct irradiance at each of the first `samples` points of every
/// patch (three channels, `n × samples` each, patch-major), and `D`, their
/// mean per patch (summed in f64).
pub fn irradiance(
    baked: &Baked,
    dl: &DirectLight,
    lights: &[Light],
    samples: usize,
) -> ([Vec<f32>; 3], [Vec<f32>; 3]) {
    let s = samples.clamp(1, SAMPLES_PER_PATCH);
    let n = baked.patches.len();
    let lights = Prepared::all(lights);
    // Per patch its points' values and their mean, written in place (no
    // allocation per patch: they showed in `perf` of the direct pass).
    let mut at = vec![[0.0f64; 3]; n * s];
    let mut mean = vec![[0.0f64; 3]; n];
    at.par_chunks_mut(s)
        .zip(mean.par_iter_mut())
        .enumerate()
        .for_each(|(j, (values, m))| {
            let mut points = [([0.0f64; 3], [0.0f64; 3]); SAMPLES_PER_PATCH];
            for (k, p) in points.iter_mut().enumerate().take(s) {
                let i = j * SAMPLES_PER_PATCH + k;
                *p = (
                    baked.samples.position[i].map(f64::from),
                    baked.samples.normal[i].map(f64::from),
                );
            }
            // The patch's points share their occluders
            // (DirectLight::at_prepared_points_into).
            dl.at_prepared_points_into(&points[..s], &lights, values);
            let mut sum = [0.0f64; 3];
            for p in values.iter() {
                for c in 0..3 {
                    sum[c] += p[c];
                }
            }
            *m = sum.map(|v| v / s as f64);
        });
    let at_points = std::array::from_fn(|c| at.iter().map(|v| v[c] as f32).collect());
    let d = std::array::from_fn(|c| mean.iter().map(|m| m[c] as f32).collect());
    (at_points, d)
}

/// `ρ_j D_jk` at each of `samples` points per patch (patch-major), from
/// [`irradiance`]'s per-point values.
pub fn reflected_at_points(baked: &Baked, d: &[Vec<f32>; 3], samples: usize) -> [Vec<f32>; 3] {
    std::array::from_fn(|c| {
        let mut out = Vec::with_capacity(d[c].len());
        for (p, points) in baked.patches.iter().zip(d[c].chunks(samples.max(1))) {
            out.extend(points.iter().map(|&dv| p.albedo[c] * dv));
        }
        out
    })
}

/// `B0 = ρ ∘ D` per channel (emission is added separately).
pub fn reflected(baked: &Baked, d: &[Vec<f32>; 3]) -> [Vec<f32>; 3] {
    std::array::from_fn(|c| {
        baked
            .patches
            .iter()
            .zip(&d[c])
            .map(|(p, &dv)| p.albedo[c] * dv)
            .collect()
    })
}

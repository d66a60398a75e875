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
    let per: Vec<(Vec<[f64; 3]>, [f64; 3])> = (0..n)
        .into_par_iter()
        .map(|j| {
            let at: Vec<([f64; 3], [f64; 3])> = (0..s)
                .map(|k| {
                    let i = j * SAMPLES_PER_PATCH + k;
                    (
                        baked.samples.position[i].map(f64::from),
                        baked.samples.normal[i].map(f64::from),
                    )
                })
                .collect();
            // The patch's points share their occluders (DirectLight::at_points_each).
            let points = dl.at_prepared_points_each(&at, &lights);
            let mut mean = [0.0f64; 3];
            for p in &points {
                for c in 0..3 {
                    mean[c] += p[c];
                }
            }
            (points, mean.map(|v| v / s as f64))
        })
        .collect();
    let at_points = std::array::from_fn(|c| {
        per.iter()
            .flat_map(|(p, _)| p.iter().map(move |v| v[c] as f32))
            .collect()
    });
    let d = std::array::from_fn(|c| per.iter().map(|(_, m)| m[c] as f32).collect());
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

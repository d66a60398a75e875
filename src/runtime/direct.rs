//! Direct light on patches per frame (DESIGN.md run time step 2): `D_j` is
//! the mean irradiance over the patch's sample points on its real triangle
//! pieces ([`crate::bakefile::surface`]), each shadowed by a ray against the
//! original triangles ([`crate::core::direct::DirectLight::at_points`], the
//! one definition of each light in [`crate::core::light`]). The first
//! [`DEFAULT_SAMPLES`] of the 16 stored points are used by default: a patch
//! half in shadow then gets 4/8 of the light, within 1/8; the points are in
//! a progressive order, so any count is spread over the patch. `B0 = ρ ∘ D
//! + E`.

use crate::bakefile::baked::Baked;
use crate::bakefile::surface::SAMPLES_PER_PATCH;
use crate::core::direct::DirectLight;
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
    let s = samples.clamp(1, SAMPLES_PER_PATCH);
    let n = baked.patches.len();
    let d: Vec<[f64; 3]> = (0..n)
        .into_par_iter()
        .map(|j| {
            let points: Vec<([f64; 3], [f64; 3])> = (0..s)
                .map(|k| {
                    let i = j * SAMPLES_PER_PATCH + k;
                    (
                        baked.samples.position[i].map(f64::from),
                        baked.samples.normal[i].map(f64::from),
                    )
                })
                .collect();
            dl.at_points(&points, lights)
        })
        .collect();
    std::array::from_fn(|c| d.iter().map(|v| v[c] as f32).collect())
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

//! Direct light on patches per frame (docs/design.md run time step 2): `D_j` is
//! the mean irradiance over the patch's sample points on its real triangle
//! pieces ([`radiosity_bakefile::surface`]), each shadowed by a ray against the
//! original triangles ([`radiosity_core::direct::DirectLight::at_points_each`],
//! which tries each light's last blocker among a patch's points before the
//! BVH; the one definition of each light is in [`radiosity_core::light`]). The first
//! [`DEFAULT_SAMPLES`] of the 16 stored points are used by default: a patch
//! half in shadow then gets 4/8 of the light, within 1/8; the points are in
//! a progressive order, so any count is spread over the patch. `B0 = ρ ∘ D
//! + E`.

use radiosity_bakefile::baked::Baked;
use radiosity_bakefile::surface::SAMPLES_PER_PATCH;
use radiosity_core::direct::DirectLight;
use radiosity_core::light::Prepared;
use radiosity_core::scene_config::Light;
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
    // Per patch its points' values and their mean, written in place into
    // the f32 outputs (no allocation per patch: they showed in `perf` of
    // the direct pass; and no f64 copy of every point's value converted
    // afterwards: that buffer, 24 bytes a point, a fresh allocation each
    // pass, made three one-light passes on the interior's 3,499 patches
    // take 3.75 ms against 3.53 ms so).
    let mut at_points: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n * s]);
    let mut d: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let [a0, a1, a2] = &mut at_points;
    let [d0, d1, d2] = &mut d;
    let points_out = (
        a0.par_chunks_mut(s),
        a1.par_chunks_mut(s),
        a2.par_chunks_mut(s),
    );
    let means_out = (d0.par_iter_mut(), d1.par_iter_mut(), d2.par_iter_mut());
    (points_out, means_out)
        .into_par_iter()
        .enumerate()
        .for_each(|(j, ((p0, p1, p2), (m0, m1, m2)))| {
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
            let mut values = [[0.0f64; 3]; SAMPLES_PER_PATCH];
            dl.at_prepared_points_into(&points[..s], &lights, &mut values[..s]);
            let mut sum = [0.0f64; 3];
            for (k, p) in values[..s].iter().enumerate() {
                for c in 0..3 {
                    sum[c] += p[c];
                }
                (p0[k], p1[k], p2[k]) = (p[0] as f32, p[1] as f32, p[2] as f32);
            }
            let mean = sum.map(|v| v / s as f64);
            (*m0, *m1, *m2) = (mean[0] as f32, mean[1] as f32, mean[2] as f32);
        });
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

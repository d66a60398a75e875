//! An independent reference for indirect light: Monte Carlo path tracing on
//! the original triangles, with no patches, form factors, transfer matrix
//! or codec involved (docs/design.md section 3, measure 4, in its in-project
//! form; the Mitsuba 3 comparison of the benchmark issue is the external
//! one). It estimates the indirect irradiance `H(x)` — the light arriving
//! at `x` from surfaces, emitted or reflected, as `H = T · B0` defines it —
//! at points of the real surfaces.
//!
//! From `x` with normal `n`, a cosine-distributed direction finds the
//! nearest triangle `y_1`: the path adds `β (E_1 + ρ_1 D_1)` — its emission
//! and its reflected direct light, `D` with a shadow ray to each light (the
//! one light definition of [`crate::core::light`]) — then continues from
//! `y_1` with `β ← β ρ_1`, and so on (the cosine pdf cancels the cosine and
//! the `1/π` of a diffuse surface's radiance). A path ends at a back face
//! (a surface emits and reflects only on its front, as the bake assumes)
//! unless the face has a back side (`Scene::twin`), which it meets instead,
//! when it leaves the scene, or by Russian roulette once `β` falls below
//! 1/8 (survival probability `8 β`, unbiased). Albedo and emission are the
//! material's (`Kd` × the texture's mean, `Ke`), as the bake's patches.
//! Seeded per point: the same inputs give the same numbers.
//!
//! Under a sky ([`PathTracer::with_sky`]) a path that leaves the scene
//! sees it: from `x` itself that is the sky's direct irradiance at `x`
//! (`π L(d)` per cosine-distributed direction; estimated apart, as the
//! run time's `D_sky`), from a later vertex it adds `β π L(d)` to `H` —
//! the sky reflected there, within the same count of reflections.

use crate::core::direct::DirectLight;
use crate::core::light::Prepared;
use crate::core::math::{add, dot, normalize, scale, tangent_basis, SplitMix64};
use crate::core::scene::Scene;
use crate::core::scene_config::Light;
use crate::core::sky::Sky;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Paths below this throughput play Russian roulette.
const ROULETTE_BELOW: f64 = 0.125;

/// The path tracer over one scene.
pub struct PathTracer<'a> {
    scene: &'a Scene,
    direct: DirectLight,
    far: f64,
    sky: Option<Sky>,
}

/// An estimate and its standard error (per channel).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    pub mean: [f64; 3],
    pub std_error: [f64; 3],
}

impl<'a> PathTracer<'a> {
    pub fn new(scene: &'a Scene) -> PathTracer<'a> {
        let direct = DirectLight::new(scene);
        let far = 4.0 * direct.far();
        PathTracer {
            scene,
            direct,
            far,
            sky: None,
        }
    }

    /// The same tracer under `sky` (module doc).
    pub fn with_sky(mut self, sky: Option<Sky>) -> PathTracer<'a> {
        self.sky = sky;
        self
    }

    /// The indirect irradiance at `x` (normal `n`) from `paths` paths,
    /// after at most `bounces` reflections (`None`: all; 1: the first
    /// reflection of direct light and the emission arriving directly).
    pub fn indirect(
        &self,
        x: [f64; 3],
        n: [f64; 3],
        lights: &[Light],
        paths: usize,
        bounces: Option<u32>,
        seed: u64,
    ) -> Estimate {
        self.indirect_and_sky(x, n, lights, paths, bounces, seed).0
    }

    /// [`PathTracer::indirect`], and the sky's direct irradiance at `x`
    /// from the same paths' first directions (0 without a sky).
    pub fn indirect_and_sky(
        &self,
        x: [f64; 3],
        n: [f64; 3],
        lights: &[Light],
        paths: usize,
        bounces: Option<u32>,
        seed: u64,
    ) -> (Estimate, Estimate) {
        let mut rng = SplitMix64::new(seed);
        let lights = Prepared::all(lights);
        let mut sums = [([0.0f64; 3], [0.0f64; 3]); 2];
        for _ in 0..paths {
            let v = self.path(x, n, &lights, bounces.unwrap_or(u32::MAX), &mut rng);
            for (k, (s, s2)) in sums.iter_mut().enumerate() {
                for c in 0..3 {
                    s[c] += v[k][c];
                    s2[c] += v[k][c] * v[k][c];
                }
            }
        }
        let k = paths.max(1) as f64;
        let estimate = |(s, s2): ([f64; 3], [f64; 3])| Estimate {
            mean: s.map(|v| v / k),
            std_error: std::array::from_fn(|c| {
                let m = s[c] / k;
                ((s2[c] / k - m * m).max(0.0) / k).sqrt()
            }),
        };
        (estimate(sums[0]), estimate(sums[1]))
    }

    fn path(
        &self,
        x0: [f64; 3],
        n0: [f64; 3],
        lights: &[Prepared],
        bounces: u32,
        rng: &mut SplitMix64,
    ) -> [[f64; 3]; 2] {
        let bvh = self.direct.bvh();
        let offset = self.direct.offset();
        let (mut x, mut n) = (x0, n0);
        let mut beta = [1.0f64; 3];
        let mut h = [0.0f64; 3];
        let mut sky_direct = [0.0f64; 3];
        let bounces = bounces.min(1000);
        for step in 0..=bounces {
            // The last step only looks for the sky past the last
            // reflection.
            if step == bounces && self.sky.is_none() {
                break;
            }
            let d = cosine_direction(n, rng);
            let o = add(x, scale(n, offset));
            let Some((k, t)) = self.direct.closest_hit(o, scale(d, self.far)) else {
                if let Some(sky) = &self.sky {
                    let l = sky.radiance(d);
                    for c in 0..3 {
                        if step == 0 {
                            sky_direct[c] = PI * l[c];
                        } else {
                            h[c] += beta[c] * PI * l[c];
                        }
                    }
                }
                break;
            };
            if step == bounces {
                break;
            }
            let mut tri = bvh.order[k as usize] as usize;
            let mut ng = self.scene.triangle_normal(tri);
            if dot(ng, d) >= 0.0 {
                // A back side (`Scene::twin`) coincides with this back face
                // and faces the path: the path meets it (the renderer's
                // rule); else the path ends.
                match self.scene.twin(tri) {
                    Some(twin) => {
                        tri = twin;
                        ng = self.scene.triangle_normal(tri);
                    }
                    None => break,
                }
            }
            let y = add(o, scale(d, t * self.far));
            let m = &self.scene.materials[self.scene.triangle_material[tri] as usize];
            let dy = self.direct.at_prepared_points(&[(y, ng)], lights);
            for c in 0..3 {
                let rho = m.albedo[c] as f64;
                h[c] += beta[c] * (m.emission[c] as f64 + rho * dy[c]);
                beta[c] *= rho;
            }
            let bmax = beta.iter().cloned().fold(0.0, f64::max);
            if bmax <= 0.0 {
                break;
            }
            if bmax < ROULETTE_BELOW {
                let survive = bmax / ROULETTE_BELOW;
                if rng.uniform() >= survive {
                    break;
                }
                beta = beta.map(|b| b / survive);
            }
            x = y;
            n = ng;
        }
        [h, sky_direct]
    }

    /// The indirect irradiance averaged over each of `points` groups
    /// (e.g. a patch's sample points), `paths` paths per point, in
    /// parallel; group `g`'s seed is `seed + g`.
    pub fn mean_over(
        &self,
        groups: &[Vec<([f64; 3], [f64; 3])>],
        lights: &[Light],
        paths: usize,
        bounces: Option<u32>,
        seed: u64,
    ) -> Vec<Estimate> {
        self.mean_over_with_sky(groups, lights, paths, bounces, seed)
            .into_iter()
            .map(|(h, _)| h)
            .collect()
    }

    /// [`PathTracer::mean_over`], and the sky's direct irradiance averaged
    /// the same way.
    pub fn mean_over_with_sky(
        &self,
        groups: &[Vec<([f64; 3], [f64; 3])>],
        lights: &[Light],
        paths: usize,
        bounces: Option<u32>,
        seed: u64,
    ) -> Vec<(Estimate, Estimate)> {
        groups
            .par_iter()
            .enumerate()
            .map(|(g, pts)| {
                let mut e = [Estimate::default(); 2];
                let k = pts.len().max(1) as f64;
                for (i, (x, n)) in pts.iter().enumerate() {
                    let s = self.indirect_and_sky(
                        *x,
                        *n,
                        lights,
                        paths,
                        bounces,
                        seed.wrapping_add((g as u64) << 20 | i as u64),
                    );
                    for (ek, sk) in e.iter_mut().zip([s.0, s.1]) {
                        for c in 0..3 {
                            ek.mean[c] += sk.mean[c] / k;
                            ek.std_error[c] += sk.std_error[c] * sk.std_error[c] / (k * k);
                        }
                    }
                }
                for ek in &mut e {
                    ek.std_error = ek.std_error.map(f64::sqrt);
                }
                (e[0], e[1])
            })
            .collect()
    }
}

/// A cosine-distributed unit direction around `n` (Malley's method).
fn cosine_direction(n: [f64; 3], rng: &mut SplitMix64) -> [f64; 3] {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    let r = u1.sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    let (t, b) = tangent_basis(normalize(n));
    let z = (1.0 - u1).max(0.0).sqrt();
    normalize(add(
        add(scale(t, r * phi.cos()), scale(b, r * phi.sin())),
        scale(n, z),
    ))
}

impl PathTracer<'_> {
    /// The fraction of cosine-distributed directions from `x` (normal `n`)
    /// that meet a front face: the share of the real hemisphere a form
    /// factor row can sum to.
    pub fn front_fraction(&self, x: [f64; 3], n: [f64; 3], rays: usize, seed: u64) -> f64 {
        let bvh = self.direct.bvh();
        let o = add(x, scale(n, self.direct.offset()));
        let mut rng = SplitMix64::new(seed);
        let mut hits = 0usize;
        for _ in 0..rays {
            let d = cosine_direction(n, &mut rng);
            if let Some((k, _)) = self.direct.closest_hit(o, scale(d, self.far)) {
                let tri = bvh.order[k as usize] as usize;
                if dot(self.scene.triangle_normal(tri), d) < 0.0 || self.scene.twin(tri).is_some() {
                    hits += 1;
                }
            }
        }
        hits as f64 / rays.max(1) as f64
    }
}

//! Direct light on patches, on the CPU: the irradiance `D_j` that the
//! lights of a scene's camera/lights file put on each patch, with shadows
//! from the original triangles, and the exitance `B0 = ρ ∘ D + E` that the
//! transfer matrix gathers (docs/design.md section 2). The run-time renderer
//! computes `D` from shadow maps on the GPU; this is the reference it will
//! be compared with, and the source of the seeded random lights that the
//! compression report measures `H = T̃ · B0` over.

use crate::bvh::Bvh;
use crate::bvh4::{Bvh4, PACKET};
use crate::light::{incident_packet, incident_prepared, Prepared, LANES};
use crate::math::{add, dot, f64s, normalize, scale, sub, SplitMix64};
use crate::patch::Patch;
use crate::scene::Scene;
use crate::scene_config::Light;
use rayon::prelude::*;

// The light's lanes are the shadow rays' packet.
const _: () = assert!(PACKET == LANES);

/// Direct light on patches, with a BVH over the scene's triangles.
pub struct DirectLight {
    bvh: Bvh,
    /// Its four-wide view, which the shadow rays traverse (same answers,
    /// [`crate::bvh4`]).
    bvh4: Bvh4,
    /// Shadow rays start this far in front of the surface (scene units):
    /// 1e-4 of the scene's extent, far above f32 rounding of the
    /// triangles and far below any feature a patch resolves.
    offset: f64,
    /// Length of rays towards directional lights: twice the scene's extent.
    far: f64,
}

impl DirectLight {
    pub fn new(scene: &Scene) -> DirectLight {
        let (lo, hi) = scene.bounds();
        let extent = (0..3)
            .map(|a| (hi[a] - lo[a]) as f64)
            .fold(0.0, f64::max)
            .max(1e-30);
        let bvh = Bvh::build(&scene.positions, &scene.triangles, [0.0; 3]);
        DirectLight {
            bvh4: Bvh4::build(&bvh),
            bvh,
            offset: 1e-4 * extent,
            far: 2.0 * extent,
        }
    }

    /// Irradiance `D` (RGB) on every patch from `lights`, averaged over the
    /// centres of the 2 × 2 quadrants of its square (for patches without
    /// sample points; the run time uses [`DirectLight::at_points`] on the
    /// patch's own sample points).
    pub fn irradiance(&self, patches: &[Patch], lights: &[Light]) -> Vec<[f64; 3]> {
        patches
            .par_iter()
            .map(|p| {
                let frame = p.frame();
                let points: Vec<([f64; 3], [f64; 3])> =
                    [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
                        .iter()
                        .map(|&(a, b)| (p.point(&frame, a, b), frame.n))
                        .collect();
                self.at_points(&points, lights)
            })
            .collect()
    }

    /// The mean irradiance over `points` (position, unit normal) from
    /// `lights`, each shadowed by the scene's triangles: a shadow ray from
    /// each point, lifted [`DirectLight::offset`] along its normal, to
    /// [`crate::light::Incident::shadow_end`] ([`crate::light`] defines each light).
    pub fn at_points(&self, points: &[([f64; 3], [f64; 3])], lights: &[Light]) -> [f64; 3] {
        self.at_prepared_points(points, &Prepared::all(lights))
    }

    /// [`DirectLight::at_points`] of lights prepared once.
    pub fn at_prepared_points(
        &self,
        points: &[([f64; 3], [f64; 3])],
        lights: &[Prepared],
    ) -> [f64; 3] {
        // Per point (in packets), then summed in order: with one light or
        // one point, the same sum term by term as one running total over
        // every (point, light).
        let mut d = [0.0; 3];
        for e in self.at_prepared_points_each(points, lights) {
            for (dc, e) in d.iter_mut().zip(e) {
                *dc += e;
            }
        }
        d.map(|v| v / points.len().max(1) as f64)
    }

    /// The irradiance at each of `points` (position, unit normal) from
    /// `lights`, [`DirectLight::at_point_cached`]'s values, their shadow
    /// rays traversing the BVH in packets: meant for points close together
    /// (a patch's sample points), whose rays to a light share their nodes.
    pub fn at_points_each(
        &self,
        points: &[([f64; 3], [f64; 3])],
        lights: &[Light],
    ) -> Vec<[f64; 3]> {
        self.at_prepared_points_each(points, &Prepared::all(lights))
    }

    /// [`DirectLight::at_points_each`] of lights prepared once (per frame,
    /// not per patch): per light, the shadow rays of up to [`PACKET`]
    /// points traverse the BVH together ([`Bvh4::any_hit_packet`], the
    /// same blocked-or-not answers), and each point sums its unblocked
    /// lights in light order, so every value is [`DirectLight::at_point_cached`]'s
    /// to the bit.
    pub fn at_prepared_points_each(
        &self,
        points: &[([f64; 3], [f64; 3])],
        lights: &[Prepared],
    ) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; points.len()];
        self.at_prepared_points_into(points, lights, &mut out);
        out
    }

    /// [`DirectLight::at_prepared_points_each`] written into `out` (one
    /// value per point), without allocating: the direct pass calls it per
    /// patch.
    pub fn at_prepared_points_into(
        &self,
        points: &[([f64; 3], [f64; 3])],
        lights: &[Prepared],
        out: &mut [[f64; 3]],
    ) {
        assert_eq!(out.len(), points.len(), "one output per point");
        for (chunk, out) in points.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
            let x: [[f64; 3]; PACKET] = std::array::from_fn(|k| {
                chunk
                    .get(k)
                    .map_or([0.0; 3], |&(x, n)| add(x, scale(n, self.offset)))
            });
            let n: [[f64; 3]; PACKET] =
                std::array::from_fn(|k| chunk.get(k).map_or([0.0; 3], |&(_, n)| n));
            let mut d = [[0.0f64; 3]; PACKET];
            for light in lights {
                let live = ((1u16 << chunk.len()) - 1) as u8;
                let inc = incident_packet(light, &x, &n, self.far, live);
                let (mask, e) = (inc.mask, inc.irradiance);
                // The segments, stopped short of a point or spot light; a
                // lane whose light is within the bias casts none.
                let mut dir = inc.dir;
                let mut cast = mask;
                for (k, dk) in dir.iter_mut().enumerate() {
                    if mask >> k & 1 != 0 {
                        match self.shadow_segment(light, *dk) {
                            Some(v) => *dk = v,
                            None => cast &= !(1 << k),
                        }
                    }
                }
                let hits = self.bvh4.any_hit_packet(&self.bvh, &x, &dir, cast);
                for k in 0..chunk.len() {
                    if mask >> k & 1 != 0 && (cast >> k & 1 == 0 || hits[k].is_none()) {
                        for (dc, ec) in d[k].iter_mut().zip(e[k]) {
                            *dc += ec;
                        }
                    }
                }
            }
            out.copy_from_slice(&d[..chunk.len()]);
        }
    }

    /// The irradiance at the point `x` with unit normal `n` from `lights`
    /// ([`Prepared::all`] of the frame's lights): per light, its incident irradiance where the shadow ray (lifted
    /// [`DirectLight::offset`] along `n`) meets no triangle, summed in
    /// light order; the one definition [`DirectLight::at_points`] and
    /// [`DirectLight::at_points_each`] use. Per light, the triangle that blocked the last shadow ray
    /// of `cache` is tried first, and only when it does not block this one
    /// is the BVH traversed ([`Bvh::hits_in_leaf`] says exactly when the
    /// traversal would have found a hit, so visibility is unchanged).
    /// Neighbouring points in the shadow of one roof then cost one
    /// triangle test each instead of a traversal.
    pub fn at_point_cached(
        &self,
        x: [f64; 3],
        n: [f64; 3],
        lights: &[Prepared],
        cache: &mut ShadowCache,
    ) -> [f64; 3] {
        let x = add(x, scale(n, self.offset));
        let mut d = [0.0; 3];
        cache.last.resize(lights.len(), None);
        for (light, blocker) in lights.iter().zip(cache.last.iter_mut()) {
            if let Some(inc) = incident_prepared(light, x, n, self.far) {
                let blocked = match self.shadow_segment(light, sub(inc.shadow_end, x)) {
                    // The light within the bias: nothing stands between.
                    None => false,
                    Some(dir) => match *blocker {
                        Some((leaf, k)) if self.bvh.hits_in_leaf(leaf, k, x, dir) => true,
                        _ => {
                            let hit = self.bvh4.any_hit_leaf(&self.bvh, x, dir);
                            if hit.is_some() {
                                *blocker = hit;
                            }
                            hit.is_some()
                        }
                    },
                };
                if !blocked {
                    for (dc, e) in d.iter_mut().zip(inc.irradiance) {
                        *dc += e;
                    }
                }
            }
        }
        d
    }

    /// The shadow segment `d` (from the lifted point to the light's
    /// [`crate::light::Incident::shadow_end`]) as the rays cast it:
    /// towards a point or spot light it stops [`DirectLight::offset`]
    /// short of the light, as it starts that far off the surface, so that
    /// a light in a surface's plane (a spot at a ceiling's height) is not
    /// shadowed by that surface at the segment's very end, where rounding
    /// alone decided hit or miss (speckled, striped light; 1 mm lower it
    /// was right). `None` where the light lies within the offset: nothing
    /// stands between. The GPU's rays do the same (crates/gl/glsl/shadow_ray.glsl).
    pub fn shadow_segment(&self, light: &Prepared, d: [f64; 3]) -> Option<[f64; 3]> {
        if let Prepared::Directional { .. } = light {
            return Some(d);
        }
        let len = dot(d, d).sqrt();
        if !(len > self.offset) {
            return None;
        }
        let s = 1.0 - self.offset / len;
        Some(d.map(|c| c * s))
    }

    /// The offset of shadow rays' origins along the normal (scene units).
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// Whether the segment `from → to` crosses no triangle.
    pub fn visible(&self, from: [f64; 3], to: [f64; 3]) -> bool {
        self.bvh4
            .any_hit_leaf(&self.bvh, from, sub(to, from))
            .is_none()
    }

    /// The nearest scene triangle on the segment `o + t d`, `t ∈ (0, 1]`
    /// (leaf-order index into [`DirectLight::bvh`] and `t`), through the
    /// four-wide view ([`Bvh4::closest_hit`]: [`Bvh::closest_hit`]'s answer).
    pub fn closest_hit(&self, o: [f64; 3], d: [f64; 3]) -> Option<(u32, f64)> {
        self.bvh4.closest_hit(&self.bvh, o, d)
    }

    /// [`DirectLight::closest_hit`] of up to [`PACKET`] segments at once
    /// (the lanes set in `mask`; [`Bvh4::closest_hit_packet`]: the same
    /// distances, the triangle named at an exact tie possibly the other).
    pub fn closest_hit_packet(
        &self,
        o: &[[f64; 3]; PACKET],
        d: &[[f64; 3]; PACKET],
        mask: u8,
    ) -> [Option<(u32, f64)>; PACKET] {
        self.bvh4.closest_hit_packet(&self.bvh, o, d, mask)
    }

    /// The BVH of the scene's triangles (world coordinates, no shift).
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// The length of shadow rays towards directional lights.
    pub fn far(&self) -> f64 {
        self.far
    }
}

/// Per light, the leaf and triangle that blocked its last shadow ray
/// ([`DirectLight::at_point_cached`]); one per thread and run of nearby
/// points (a patch's sample points, a row of pixels).
#[derive(Clone, Debug, Default)]
pub struct ShadowCache {
    last: Vec<Option<(u32, u32)>>,
}

impl ShadowCache {
    /// An empty cache for `lights` lights (it grows if asked for more).
    pub fn new(lights: usize) -> ShadowCache {
        ShadowCache {
            last: vec![None; lights],
        }
    }
}

/// `B0 = ρ ∘ D + E` per patch.
pub fn exitance(patches: &[Patch], d: &[[f64; 3]]) -> Vec<[f64; 3]> {
    patches
        .iter()
        .zip(d)
        .map(|(p, d)| std::array::from_fn(|c| p.albedo[c] * d[c] + p.emission[c]))
        .collect()
}

/// `B0 = ρ ∘ D + E` (f32, per channel) on `patches` for each of `count`
/// seeded random lights ([`random_lights`]) alone: the samples over which
/// the compression error of `H = T̃ · B0` is measured.
pub fn light_samples(
    scene: &Scene,
    patches: &[Patch],
    count: usize,
    seed: u64,
) -> Vec<[Vec<f32>; 3]> {
    let lights = random_lights(scene.bounds(), count, seed);
    let dl = DirectLight::new(scene);
    lights
        .iter()
        .map(|l| {
            let b0 = exitance(patches, &dl.irradiance(patches, std::slice::from_ref(l)));
            std::array::from_fn(|c| b0.iter().map(|b| b[c] as f32).collect())
        })
        .collect()
}

/// `count` seeded random lights for a scene with `bounds`: even indices
/// directional (travelling downwards at 15°–75° from the vertical, unit
/// irradiance), odd indices spot lights (inside the middle 80 % of the
/// bounds, aimed at a random point of the bounds, cone 30°–60°, beam two
/// thirds of the cone, intensity `extent²` so irradiance is O(1)).
pub fn random_lights(bounds: ([f32; 3], [f32; 3]), count: usize, seed: u64) -> Vec<Light> {
    let mut rng = SplitMix64::new(seed);
    let (lo, hi) = (f64s(bounds.0), f64s(bounds.1));
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    let inside = |rng: &mut SplitMix64, margin: f64| -> [f64; 3] {
        std::array::from_fn(|a| {
            lo[a] + (hi[a] - lo[a]) * (margin + (1.0 - 2.0 * margin) * rng.uniform())
        })
    };
    (0..count)
        .map(|i| {
            if i % 2 == 0 {
                let theta = (15.0 + 60.0 * rng.uniform()).to_radians();
                let phi = 2.0 * std::f64::consts::PI * rng.uniform();
                let dir = [
                    theta.sin() * phi.cos(),
                    -theta.cos(),
                    theta.sin() * phi.sin(),
                ];
                Light::Directional {
                    direction: dir.map(|x| x as f32),
                    irradiance: [1.0; 3],
                }
            } else {
                let pos = inside(&mut rng, 0.1);
                let mut target = inside(&mut rng, 0.0);
                if dot(sub(target, pos), sub(target, pos)) == 0.0 {
                    target[1] -= 1.0;
                }
                let cone = 30.0 + 30.0 * rng.uniform();
                let i = (extent * extent) as f32;
                Light::Spot {
                    position: pos.map(|x| x as f32),
                    direction: normalize(sub(target, pos)).map(|x| x as f32),
                    intensity: [i; 3],
                    cone_angle_deg: cone as f32,
                    beam_angle_deg: (cone * 2.0 / 3.0) as f32,
                }
            }
        })
        .collect()
}

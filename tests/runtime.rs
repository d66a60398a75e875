//! The CPU run time (crates/runtime/src/) on baked scenes generated here: energy
//! balance in a closed box, lights outside a closed room, incremental
//! updates against full products, colour bleeding in the Cornell box
//! measured on pixels, the surface map's smoothness on a wall of two
//! triangles, per-material emission, the direct pass against the core's
//! direct light per point.

// Index loops over channels and patches read several arrays at once.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{quad, write_quads, Quad};
use radiosity::bake::voxelize::Resolution;
use radiosity::bake::{self, BakeConfig, CodecChoice, ComputeChoice};
use radiosity::bakefile::baked::Baked;
use radiosity::bakefile::codec::CodecKind;
use radiosity::core::math::SplitMix64;
use radiosity::core::scene;
use radiosity::core::scene_config::{self, Light};
use radiosity::runtime::render::{render, View};
use radiosity::runtime::texture::Albedo;
use radiosity::runtime::{Runtime, RuntimeOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Bakes `obj` (CPU-independent options, OpenCL device) and loads it.
fn bake(obj: &Path, resolution: Resolution, codec: CodecKind) -> (Runtime, PathBuf) {
    let mut c = BakeConfig::new(obj.to_path_buf(), resolution);
    c.compute = ComputeChoice::OpenCl(Default::default());
    c.codec = CodecChoice::Fixed(codec);
    c.error_lights = 0;
    let out = obj.with_extension("rad");
    c.output = Some(out.clone());
    common::gpu();
    bake::run(&c, &mut |_| {}).expect("bake");
    let baked = Baked::load(&out).unwrap();
    let s = scene::load(obj).unwrap();
    (Runtime::new(baked, s, RuntimeOptions::default()), out)
}

/// The inward faces of the box `[0, sx] × [0, sy] × [0, sz]`, albedo `a`.
fn box_inward(s: [f64; 3], a: f64) -> Vec<Quad> {
    let mut q = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0.0, 1.0] {
            let mut c = [s[0] / 2.0, s[1] / 2.0, s[2] / 2.0];
            c[axis] = side * s[axis];
            let mut eu = [0.0; 3];
            eu[u] = 1.0;
            let mut ev = [0.0; 3];
            ev[v] = 1.0;
            // Inward normal +axis at side 0 (u × v = +axis), −axis at side 1.
            if side == 1.0 {
                ev[v] = -1.0;
            }
            q.push(quad(c, eu, ev, s[u] / 2.0, s[v] / 2.0, [a; 3]));
        }
    }
    q
}

/// A coloured spot somewhere in the Cornell box, pointing down-ish.
fn cornell_spot(rng: &mut SplitMix64) -> Light {
    Light::Spot {
        position: [
            50.0 + 450.0 * rng.uniform() as f32,
            50.0 + 450.0 * rng.uniform() as f32,
            50.0 + 450.0 * rng.uniform() as f32,
        ],
        direction: [rng.uniform() as f32 - 0.5, -1.0, rng.uniform() as f32 - 0.5],
        intensity: [30000.0, 20000.0, 10000.0],
        cone_angle_deg: 20.0 + 40.0 * rng.uniform() as f32,
        beam_angle_deg: 10.0,
    }
}

fn point(p: [f32; 3], i: f32) -> Light {
    Light::Point {
        position: p,
        intensity: [i; 3],
    }
}

#[test]
fn closed_box_balances_energy_and_every_shadowed_patch_gets_indirect_light() {
    let rho = 0.5;
    let mut quads = box_inward([1.0, 1.0, 1.0], rho);
    // A plate above the floor shadows part of it (facing up; its underside
    // is not modelled, so it blocks without receiving).
    quads.push(quad(
        [0.3, 0.3, 0.3],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        0.2,
        0.2,
        [rho; 3],
    ));
    let obj = write_quads("rt-box", &quads);
    let (mut rt, _) = bake(&obj, Resolution::VoxelSize(0.125), CodecKind::default());
    let lights = [point([0.5, 0.8, 0.5], 1.0)];
    rt.frame(&lights, &BTreeMap::new());
    let n = rt.n();
    let (d, h) = (rt.d().clone(), rt.h().clone());
    let mut shadowed = 0;
    for j in 0..n {
        if d[0][j] == 0.0 {
            shadowed += 1;
            assert!(
                h[0][j] > 0.0,
                "patch {j} gets neither direct nor indirect light"
            );
        }
    }
    assert!(shadowed > 0, "the plate shadows some patches");
    // Energy: in a closed environment with uniform albedo ρ (row sums 1,
    // reciprocity), Σ A H = Σ A B0 / (1 − ρ) with B0 = ρ D. The plate makes
    // the box not quite closed (its underside is open to the floor), so
    // only the box's own patches are summed and both sides include what
    // the plate exchanges; the tolerance (3 %) covers the codec's error on
    // H (≈ 2 % relative RMS, less on an area-weighted sum, which the mass
    // correction keeps) and the form factors' row sums.
    let (mut lhs, mut rhs) = (0.0f64, 0.0f64);
    for (j, p) in rt.baked.patches.iter().enumerate() {
        let a = p.area as f64;
        lhs += a * h[0][j] as f64;
        rhs += a * rho * d[0][j] as f64 / (1.0 - rho);
    }
    let rel = (lhs / rhs - 1.0).abs();
    assert!(
        rel < 0.03,
        "Σ A H = {lhs}, Σ A ρ D / (1 − ρ) = {rhs}: {rel:.4}"
    );
}

/// The run time's direct pass (`runtime::direct::irradiance`: per patch its
/// first `s` sample points, written per channel, and their mean in f64)
/// gives, bit for bit, the core's direct light at those points
/// (`DirectLight::at_prepared_points_each`) and their mean, for 1 to 16
/// points and several lights at once, partly shadowed.
#[test]
fn the_direct_pass_is_the_core_direct_light_at_each_point_and_its_mean() {
    use radiosity::bakefile::surface::SAMPLES_PER_PATCH;
    use radiosity::core::light::Prepared;
    use radiosity::runtime::direct::irradiance;
    let mut quads = box_inward([1.0, 0.75, 1.25], 0.6);
    quads.push(quad(
        [0.4, 0.35, 0.5],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        0.2,
        0.3,
        [0.6; 3],
    ));
    let obj = write_quads("rt-direct-pass", &quads);
    let (rt, _) = bake(&obj, Resolution::VoxelSize(0.125), CodecKind::default());
    let lights = [
        point([0.5, 0.6, 0.6], 1.5),
        Light::Spot {
            position: [0.2, 0.7, 0.3],
            direction: [0.3, -1.0, 0.5],
            intensity: [2.0, 1.0, 0.5],
            cone_angle_deg: 50.0,
            beam_angle_deg: 20.0,
        },
    ];
    let prepared = Prepared::all(&lights);
    let n = rt.n();
    let mut shadowed = 0;
    for s in [1usize, 5, 8, 16] {
        let (at, d) = irradiance(&rt.baked, &rt.direct, &lights, s);
        for j in 0..n {
            let points: Vec<([f64; 3], [f64; 3])> = (0..s)
                .map(|k| {
                    let i = j * SAMPLES_PER_PATCH + k;
                    (
                        rt.baked.samples.position[i].map(f64::from),
                        rt.baked.samples.normal[i].map(f64::from),
                    )
                })
                .collect();
            let want = rt.direct.at_prepared_points_each(&points, &prepared);
            let mut sum = [0.0f64; 3];
            for (k, w) in want.iter().enumerate() {
                shadowed += usize::from(w[0] == 0.0);
                for c in 0..3 {
                    sum[c] += w[c];
                    assert_eq!(
                        at[c][j * s + k].to_bits(),
                        (w[c] as f32).to_bits(),
                        "s {s} patch {j} point {k}"
                    );
                }
            }
            for c in 0..3 {
                assert_eq!(
                    d[c][j].to_bits(),
                    ((sum[c] / s as f64) as f32).to_bits(),
                    "s {s} patch {j}"
                );
            }
        }
    }
    assert!(shadowed > 0, "some points are dark");
}

#[test]
fn a_light_outside_a_closed_room_changes_nothing_inside_bit_for_bit() {
    let obj = write_quads("rt-outside", &box_inward([1.0, 0.75, 1.25], 0.6));
    let (mut rt, _) = bake(&obj, Resolution::VoxelSize(0.125), CodecKind::default());
    let inside = point([0.5, 0.4, 0.6], 2.0);
    rt.frame(std::slice::from_ref(&inside), &BTreeMap::new());
    let h0 = rt.h().clone();
    assert!(h0[0].iter().any(|&v| v > 0.0));
    let mut rng = SplitMix64::new(3);
    for _ in 0..10 {
        let p = [
            3.0 + rng.uniform() as f32,
            -2.0 + 4.0 * rng.uniform() as f32,
            3.0 * rng.uniform() as f32,
        ];
        rt.frame(&[inside.clone(), point(p, 50.0)], &BTreeMap::new());
        for c in 0..3 {
            for (a, b) in rt.h()[c].iter().zip(&h0[c]) {
                assert_eq!(a.to_bits(), b.to_bits());
            }
        }
    }
}

#[test]
fn incremental_frames_equal_a_full_product_after_100_light_moves() {
    let obj = common::bundled_copy("cornell_box", "rt-incr");
    let (with_near, _) = bake(&obj, Resolution::VoxelSize(60.0), CodecKind::default());
    assert!(
        !with_near.near.is_empty(),
        "the bake has a near-field correction"
    );
    // The sum of terms against one full product `T̃ B0` (below) holds for
    // the plain gather; with the near-field correction, the cached run time
    // must equal one that recomputes every term, bit for bit.
    let plain = |near_field: bool, cache: bool| {
        Runtime::new(
            with_near.baked.clone(),
            with_near.scene.clone(),
            RuntimeOptions {
                near_field,
                cache,
                ..RuntimeOptions::default()
            },
        )
    };
    let mut rt = plain(false, true);
    let mut cached = plain(true, true);
    let mut fresh = plain(true, false);
    let n = rt.n();
    let mut rng = SplitMix64::new(11);
    let mut lights: Vec<Light> = (0..3)
        .map(|_| point([278.0, 400.0, 279.0], 20000.0))
        .collect();
    let u = f32::EPSILON as f64 / 2.0;
    for step in 0..100 {
        let k = step % 3;
        lights[k] = cornell_spot(&mut rng);
        let s = rt.frame(&lights, &BTreeMap::new());
        if step > 0 {
            assert_eq!(s.terms_computed, 1, "only the moved light is recomputed");
        }
        let s = cached.frame(&lights, &BTreeMap::new());
        if step > 0 {
            assert_eq!(s.terms_computed, 1, "with the near field too");
        }
        fresh.frame(&lights, &BTreeMap::new());
        assert_eq!(
            cached.h(),
            fresh.h(),
            "step {step}: cached against recomputed"
        );
        let b0 = rt.b0().clone();
        let (full, _, _) = rt.product(&b0);
        // Each product of non-negative terms errs by at most γ_n of the
        // exact value (Higham §3.1); the run time's H adds the 4 terms'
        // products (3 more roundings), and B0's sum of terms rounds too.
        let g = n as f64 * u / (1.0 - n as f64 * u);
        let bound = 2.0 * g + 8.0 * u;
        for c in 0..3 {
            for j in 0..n {
                let (a, b) = (rt.h()[c][j] as f64, full[c][j] as f64);
                assert!(
                    (a - b).abs() <= bound * b.abs().max(1e-30) * 1.01 + 1e-30,
                    "step {step}: H[{c}][{j}] {a} vs a full product {b}"
                );
            }
        }
    }
}

/// Culling negligible columns in frames (`RuntimeOptions::cull`): over
/// 60 moves of three spot lights, the cached run time equals one that
/// recomputes every term, bit for bit (each term is a fresh culled
/// product, so nothing drifts); against the exact run time, `H` differs
/// by at most the dropped groups' bound in L1, summed over the terms
/// (plus f32 rounding: `γ_n` of the bound's total per product, and the
/// sum of terms); and culling does drop columns.
#[test]
fn culled_frames_stay_within_their_bound_without_drift() {
    let obj = common::bundled_copy("cornell_box", "rt-cull");
    let (exact, _) = bake(&obj, Resolution::VoxelSize(60.0), CodecKind::default());
    let with = |cull: f64, cache: bool| {
        Runtime::new(
            exact.baked.clone(),
            exact.scene.clone(),
            RuntimeOptions {
                cull,
                cache,
                ..RuntimeOptions::default()
            },
        )
    };
    let eps = 1e-3;
    let (mut cached, mut fresh, mut exact) = (with(eps, true), with(eps, false), with(0.0, true));
    let n = exact.n();
    let u = f32::EPSILON as f64 / 2.0;
    let g = n as f64 * u / (1.0 - n as f64 * u);
    let mut rng = SplitMix64::new(5);
    let mut lights: Vec<Light> = (0..3)
        .map(|_| point([278.0, 400.0, 279.0], 20000.0))
        .collect();
    let mut culled = 0;
    for step in 0..60 {
        lights[step % 3] = cornell_spot(&mut rng);
        cached.frame(&lights, &BTreeMap::new());
        let s = fresh.frame(&lights, &BTreeMap::new());
        exact.frame(&lights, &BTreeMap::new());
        assert_eq!(
            cached.h(),
            fresh.h(),
            "step {step}: cached against recomputed"
        );
        assert!(s.gather.culled_mass <= eps * s.gather.mass, "step {step}");
        culled += s.gather.culled_groups;
        let diff: f64 = (0..3)
            .flat_map(|c| (0..n).map(move |j| (c, j)))
            .map(|(c, j)| (cached.h()[c][j] as f64 - exact.h()[c][j] as f64).abs())
            .sum();
        let total: f64 = exact.h().iter().flatten().map(|&v| (v as f64).abs()).sum();
        let slack = 2.0 * g * s.gather.mass + 8.0 * u * total;
        assert!(
            diff <= s.gather.culled_mass + slack,
            "step {step}: L1 difference {diff} > bound {} + {slack}",
            s.gather.culled_mass
        );
    }
    assert!(culled > 0, "culling dropped no column in 60 frames");
    // Culling switched off between frames: the cached terms, culled, are
    // recomputed, and the frame is the exact one.
    cached.options.cull = 0.0;
    let s = cached.frame(&lights, &BTreeMap::new());
    assert_eq!(s.terms_computed, 4, "the emission and the three lights");
    assert_eq!(cached.h(), exact.h());
    // Fewer sample points after the run time was made: recomputed with the
    // near-field weights of that count, as a run time made with it.
    for samples in [2, 16, 8] {
        cached.options.samples = samples;
        cached.frame(&lights, &BTreeMap::new());
        let mut made_with = Runtime::new(
            exact.baked.clone(),
            exact.scene.clone(),
            RuntimeOptions {
                samples,
                ..RuntimeOptions::default()
            },
        );
        made_with.frame(&lights, &BTreeMap::new());
        assert_eq!(cached.h(), made_with.h(), "{samples} sample points");
        // One light's term from points lit with that count, asked of a run
        // time whose weights are for another (`exact`'s default): the same.
        let (d_points, d) = radiosity::runtime::direct::irradiance(
            &exact.baked,
            &exact.direct,
            &lights[..1],
            samples,
        );
        let b0 = radiosity::runtime::direct::reflected(&exact.baked, &d);
        assert_eq!(
            exact.light_product(&b0, &d_points).0,
            made_with.light_product(&b0, &d_points).0,
            "{samples} sample points, one term"
        );
    }
}

#[test]
fn cornell_box_wall_next_to_the_red_wall_receives_more_red_on_pixels() {
    let obj = common::bundled_copy("cornell_box", "rt-cornell");
    let dir = obj.parent().unwrap().to_path_buf();
    let (mut rt, _) = bake(&obj, Resolution::VoxelSize(40.0), CodecKind::default());
    let config = scene_config::load(&dir.join("cornell_box.json")).unwrap();
    rt.frame(&config.lights, &config.emission);
    let albedo = Albedo::new(&rt.scene);
    let (w, h) = (160, 120);
    let (img, stats) = render(&rt, &config, View::Indirect, w, h, &albedo);
    assert_eq!(stats.unmapped, 0);
    // The back wall, above the blocks: its left part (next to the red wall,
    // on the left of the camera) against its right part (next to the green).
    let mean = |x0: f64, x1: f64| {
        let mut s = [0.0f64; 3];
        let mut k = 0;
        for y in (0.2 * h as f64) as usize..(0.35 * h as f64) as usize {
            for x in (x0 * w as f64) as usize..(x1 * w as f64) as usize {
                let p = img.radiance[y * w + x];
                for c in 0..3 {
                    s[c] += p[c] as f64;
                }
                k += 1;
            }
        }
        s.map(|v| v / k as f64)
    };
    let left = mean(0.30, 0.36);
    let right = mean(0.64, 0.70);
    assert!(
        left[0] > left[1],
        "next to the red wall: red {} > green {}",
        left[0],
        left[1]
    );
    // The light is warm (Ke 17 : 12 : 4), so white surfaces are redder
    // than green everywhere; the red wall makes its side redder still.
    assert!(
        left[0] / left[1] > 1.1 * (right[0] / right[1]),
        "red/green next to the red wall {} against next to the green wall {}",
        left[0] / left[1],
        right[0] / right[1]
    );
}

#[test]
fn a_wall_of_two_triangles_shows_a_smooth_gradient_of_indirect_light() {
    // A 4 × 4 floor (one quad: two triangles) and a 4 × 2 wall standing on
    // its edge at x = 0, both grey; a point light close to the wall lights
    // the wall strongly and the floor's far end little, so the floor's
    // indirect light (mostly from the wall) falls with x.
    let quads = vec![
        quad(
            [2.0, 0.0, 2.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            2.0,
            2.0,
            [0.6; 3],
        ),
        quad(
            [0.0, 1.0, 2.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            1.0,
            2.0,
            [0.8; 3],
        ),
    ];
    let obj = write_quads("rt-gradient", &quads);
    let (rt, _) = bake(&obj, Resolution::VoxelSize(0.25), CodecKind::F32);
    // The surface map's own interpolation, without the near field's
    // deviations at the receiver (the bake's counts left out): monotone
    // from the peak up to f32 rounding. With them: the same profile but
    // for their cells' ray noise (about 256 rays a cell: a ripple of
    // 0.06 % of H measured where the profile is flat at its peak, bound
    // 0.5 %), still without steps.
    let mut plain = rt.baked.clone();
    plain.near_field.cast.clear();
    let plain = Runtime::new(plain, scene::load(&obj).unwrap(), RuntimeOptions::default());
    assert!(rt.h_points().is_none(), "no frame yet");
    assert!(
        !rt.baked.near_field.cast.is_empty(),
        "the bake counts by the receiver's cell"
    );
    for (mut rt, ripple) in [(plain, 1e-6), (rt, 5e-3)] {
        floor_profile_falls_smoothly(&mut rt, ripple);
    }
}

/// The floor's middle row of [`a_wall_of_two_triangles_shows_a_smooth_gradient_of_indirect_light`]
/// seen from above: after its peak near the wall it falls, rising by at most
/// `ripple` of its value between neighbouring pixels, and without steps.
fn floor_profile_falls_smoothly(rt: &mut Runtime, ripple: f64) {
    rt.frame(&[point([0.3, 1.0, 2.0], 2.0)], &BTreeMap::new());
    // Looking straight down at the floor.
    let config = scene_config::SceneConfig {
        sky: None,
        objects: Vec::new(),
        emission: BTreeMap::new(),
        camera: scene_config::Camera {
            position: [2.0, 6.0, 2.0],
            target: [2.0, 0.0, 2.0],
            up: [0.0, 0.0, -1.0],
            fov_y_deg: 40.0,
        },
        lights: vec![point([0.3, 1.0, 2.0], 2.0)],
        units: "m".into(),
        description: String::new(),
    };
    let albedo = Albedo::new(&rt.scene);
    let (w, h) = (200, 200);
    let (img, _) = render(rt, &config, View::Indirect, w, h, &albedo);
    // The middle row, from x ≈ 0.4 to x ≈ 3.6 (pixels whose floor point
    // lies inside the floor's interior voxels).
    let y = h / 2;
    let row: Vec<f64> = (0..w)
        .filter(|&x| img.covered[y * w + x])
        .map(|x| img.radiance[y * w + x][0] as f64)
        .collect();
    let m = row.len();
    // The floor's indirect light rises over the first half metre (the
    // wall's brightest band is seen at a steeper angle there), then falls:
    // from its peak on it must fall monotonically.
    let inner = &row[m / 10..m - m / 10];
    let peak = (0..inner.len())
        .max_by(|&a, &b| inner[a].total_cmp(&inner[b]))
        .unwrap();
    assert!(peak < inner.len() / 4, "the peak lies near the wall");
    let line = &inner[peak..];
    let range = line.first().unwrap() - line.last().unwrap();
    assert!(range > 0.0, "the floor is lit more near the wall");
    let mean_step = range / (line.len() - 1) as f64;
    for (k, p) in line.windows(2).enumerate() {
        let d = p[0] - p[1];
        // Monotone (up to `ripple`), and no step: bilinear weights make H
        // continuous, so adjacent pixels differ by the local slope, at
        // most a few times the mean slope.
        assert!(
            d >= -ripple * p[0].abs(),
            "pixel {k}: rises from {} to {} (ripple {ripple})",
            p[0],
            p[1]
        );
        assert!(
            d <= 4.0 * mean_step,
            "pixel {k}: step {d} against a mean slope {mean_step}"
        );
    }
}

#[test]
fn emission_scales_per_material_and_reproduces_the_stored_emission() {
    let obj = common::bundled_copy("cornell_box", "rt-emission");
    let (mut rt, _) = bake(&obj, Resolution::VoxelSize(60.0), CodecKind::default());
    let n = rt.n();
    let e = rt.emission.exitance(n, &BTreeMap::new());
    for (j, p) in rt.baked.patches.iter().enumerate() {
        for c in 0..3 {
            assert!(
                (e[c][j] - p.emission[c]).abs() <= 1e-4 * p.emission[c].max(1.0),
                "patch {j}: {} vs stored {}",
                e[c][j],
                p.emission[c]
            );
        }
    }
    assert_eq!(rt.emission.materials, ["light"]);
    rt.frame(&[], &BTreeMap::new());
    let h1 = rt.h().clone();
    assert!(h1[0].iter().sum::<f32>() > 0.0);
    let mut half = BTreeMap::new();
    half.insert("light".to_string(), 0.5f32);
    rt.frame(&[], &half);
    for c in 0..3 {
        for j in 0..n {
            assert!((rt.h()[c][j] - 0.5 * h1[c][j]).abs() <= 1e-5 * h1[c][j].max(1e-30));
        }
    }
    half.insert("light".to_string(), 0.0);
    rt.frame(&[], &half);
    assert!(rt.h().iter().all(|c| c.iter().all(|&v| v == 0.0)));
}

/// More lights than the term cache holds (`RuntimeOptions::
/// term_cache_bytes`, here three terms' worth for seven lights): lights
/// share terms in threes, `H` is the one-light-per-term `H` within f32
/// rounding, and a moved light recomputes only its group.
#[test]
fn lights_beyond_the_term_budget_share_terms() {
    use radiosity::runtime::{lights_per_term, TERM_BYTES_PER_PATCH};
    let obj = common::bundled_copy("cornell_box", "rt-groups");
    let (single, _) = bake(&obj, Resolution::VoxelSize(60.0), CodecKind::default());
    let n = single.n();
    let budget = 3 * TERM_BYTES_PER_PATCH * n;
    assert_eq!(lights_per_term(7, n, budget), 3);
    assert_eq!(lights_per_term(3, n, budget), 1);
    assert_eq!(lights_per_term(0, n, budget), 1);
    assert_eq!(lights_per_term(5, n, 0), 5, "at least one term");
    let mut grouped = Runtime::new(
        single.baked.clone(),
        single.scene.clone(),
        RuntimeOptions {
            term_cache_bytes: budget,
            ..RuntimeOptions::default()
        },
    );
    let mut single = single;
    let mut lights: Vec<Light> = (0..7)
        .map(|i| point([80.0 + 60.0 * i as f32, 450.0, 279.0], 5000.0))
        .collect();
    let none = BTreeMap::new();
    let s = grouped.frame(&lights, &none);
    assert_eq!(
        (s.terms_computed, s.terms_reused),
        (4, 0),
        "emission and 3 groups"
    );
    single.frame(&lights, &none);
    // The same products of non-negative terms summed in other groupings:
    // each within γ_n and a few roundings of the exact H (Higham §3.1).
    let u = f32::EPSILON as f64 / 2.0;
    let bound = 2.0 * (n as f64 * u / (1.0 - n as f64 * u) + 16.0 * u);
    let close = |a: &[Vec<f32>; 3], b: &[Vec<f32>; 3], what: &str| {
        for c in 0..3 {
            for j in 0..n {
                let (x, y) = (a[c][j] as f64, b[c][j] as f64);
                assert!(
                    (x - y).abs() <= bound * y.abs() + 1e-30,
                    "{what}: H[{c}][{j}] {x} grouped against {y}"
                );
            }
        }
    };
    close(grouped.h(), single.h(), "first frame");
    lights[4] = point([300.0, 200.0, 150.0], 8000.0);
    let s = grouped.frame(&lights, &none);
    assert_eq!(
        (s.terms_computed, s.terms_reused),
        (1, 3),
        "only the moved light's group"
    );
    single.frame(&lights, &none);
    close(grouped.h(), single.h(), "after a move");
}

/// `examples/embed.rs`, the README's embedding example, run here.
#[path = "../examples/embed.rs"]
mod embed;

/// What an application embedding the run time does (`examples/embed.rs`):
/// open a bake with its scene, light it frame after frame with a spot that
/// swings, read `D` and `H` at a point of the scene. The spot's direct
/// light at the probe is the closed form `I cos θ / r²` (the probe lies
/// inside the beam), each frame after the first recomputes only the
/// spot's product; and a scene that is not the one baked is refused,
/// naming what changed, in the library and on the command line.
#[test]
fn an_application_opens_a_bake_lights_it_and_reads_light_at_points() {
    let obj = common::bundled_copy("cornell_box", "rt-embed");
    let dir = obj.parent().unwrap().to_path_buf();
    let (_, rad) = bake(&obj, Resolution::VoxelSize(60.0), CodecKind::default());
    let frames = embed::run(&rad, 4).expect("the example runs");
    assert_eq!(frames.len(), 4);
    let opened = Runtime::open(&rad, None, RuntimeOptions::default()).unwrap();
    // Rays that are not rays meet nothing; a triangle that does not exist
    // has no indirect light.
    assert_eq!(opened.first_hit([278.0, 273.0, 279.0], [0.0; 3]), None);
    assert_eq!(
        opened.first_hit([f64::NAN, 273.0, 279.0], [0.0, -1.0, 0.0]),
        None
    );
    assert_eq!(opened.indirect_at(usize::MAX, [0.0; 3]), [0.0; 3]);
    for (k, f) in frames.iter().enumerate() {
        let expect = if k == 0 { (2, 0) } else { (1, 1) };
        assert_eq!((f.terms_computed, f.terms_reused), expect, "frame {k}");
        let (tri, x) = f
            .probe
            .expect("the ray down from the centre meets the floor or a block");
        let Light::Spot {
            position,
            intensity,
            ..
        } = f.light
        else {
            unreachable!()
        };
        let n = opened.scene.triangle_normal(tri);
        // The direct light is evaluated where shadow rays start: the point
        // lifted off its surface along the normal.
        let x: [f64; 3] = std::array::from_fn(|c| x[c] + opened.direct.offset() * n[c]);
        let l: [f64; 3] = std::array::from_fn(|c| position[c] as f64 - x[c]);
        let r2: f64 = l.iter().map(|v| v * v).sum();
        let cos = (0..3).map(|c| n[c] * l[c]).sum::<f64>() / r2.sqrt();
        for c in 0..3 {
            let want = intensity[c] as f64 * cos / r2;
            // The light's definition in f64 from the same f32 inputs, in
            // another order of operations: a few ulps.
            assert!(
                (f.direct[c] - want).abs() <= 1e-12 * want,
                "frame {k}: D {} against I cos / r² {want}",
                f.direct[c]
            );
            // The lamp and the spot light the box: every point gets
            // indirect light, and the mean over the patches too.
            assert!(f.indirect[c] > 0.0 && f.mean_h[c] > 0.0, "frame {k}: {f:?}");
        }
    }
    // The spot swings: the probe's indirect light follows.
    assert_ne!(frames[0].indirect, frames[1].indirect);

    // A scene given elsewhere, with the same files, opens.
    let elsewhere = dir.join("copy");
    std::fs::create_dir_all(&elsewhere).unwrap();
    for f in ["cornell_box.obj", "cornell_box.mtl"] {
        std::fs::copy(dir.join(f), elsewhere.join(f)).unwrap();
    }
    let given = elsewhere.join("cornell_box.obj");
    let rt = Runtime::open(&rad, Some(&given), RuntimeOptions::default()).expect("same files");
    assert_eq!(rt.scene.source, given);
    // Changed files are named.
    use radiosity::runtime::open::OpenError;
    for (file, changed) in [("cornell_box.obj", "obj"), ("cornell_box.mtl", "mtl")] {
        let path = dir.join(file);
        let original = std::fs::read(&path).unwrap();
        let mut edited = original.clone();
        edited.extend_from_slice(b"\n# edited after the bake\n");
        std::fs::write(&path, &edited).unwrap();
        match Runtime::open(&rad, None, RuntimeOptions::default()) {
            Err(OpenError::SceneChanged {
                changed: c, scene, ..
            }) => {
                assert_eq!(c, vec![changed]);
                assert_eq!(scene, obj);
            }
            other => panic!("{file} edited: {:?}", other.err()),
        }
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_radiosity"))
            .args(["render", rad.to_str().unwrap(), "-o"])
            .arg(dir.join("x.png"))
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(
            e.contains("different scene") && e.contains(&format!("({changed})")),
            "{e}"
        );
        assert!(!dir.join("x.png").exists());
        std::fs::write(&path, &original).unwrap();
    }
    // A missing scene names the path looked for.
    std::fs::rename(&obj, dir.join("moved.obj")).unwrap();
    let e = Runtime::open(&rad, None, RuntimeOptions::default()).err();
    match &e {
        Some(OpenError::Scene { path, .. }) => assert_eq!(path, &obj),
        other => panic!("scene moved away: {other:?}"),
    }
    assert!(e.unwrap().to_string().contains("cornell_box.obj"));
}

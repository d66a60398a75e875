//! The GL run time (crates/gl/src/: shadow maps, direct light on patches, the
//! gather, per-fragment shading) against the CPU run time that defines
//! every quantity (crates/runtime/src/), on a headless EGL context (Mesa llvmpipe
//! here; the tests fail, naming what to install, where there is none).
//!
//! Where the two differ, and why the bounds below hold:
//! - **Shadows.** The CPU casts a ray per point; the GPU reads a shadow map
//!   filtered over 4 × 4 texels. They agree except within about two texels
//!   of a shadow edge, where the GPU's shadow is a ramp: per patch `D`
//!   differs where a sample point lies in that band, so `D` is compared in
//!   relative RMS over all patches, not per patch.
//! - **The gather** decodes BC1 as llvmpipe rounds it (at most one log
//!   step, tests/gl_gather.rs), so `H` computed by the GL gather from the GL
//!   `B0` agrees with the CPU gather of the same `B0` within `e^{L/255} − 1`
//!   of each value.
//! - **Pixels** are sampled at the same centres (rasterisation and the CPU's
//!   primary rays); the surface map is evaluated in f32 on the GPU and f64
//!   on the CPU, which changes a voxel only for points within f32 rounding
//!   of a voxel face.

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
use radiosity::core::scene_config::{self, Light, SceneConfig};
use radiosity::gl::context::Headless;
use radiosity::gl::renderer::{GlOptions, GlRenderer};
use radiosity::gl::{compile_program, GlError, Stage};
use radiosity::runtime::gather::ActiveColumns;
use radiosity::runtime::render::{render, View};
use radiosity::runtime::texture::Albedo;
use radiosity::runtime::{Runtime, RuntimeOptions};
use std::collections::BTreeMap;
use std::path::Path;

fn context() -> Headless {
    Headless::new().unwrap_or_else(|e| {
        panic!("no headless OpenGL 4.5 (EGL on Mesa llvmpipe: run scripts/setup): {e}")
    })
}

/// Bakes `obj` on the OpenCL device and loads it.
fn bake(obj: &Path, resolution: Resolution) -> Runtime {
    let mut c = BakeConfig::new(obj.to_path_buf(), resolution);
    c.compute = ComputeChoice::OpenCl(Default::default());
    c.codec = CodecChoice::Fixed(CodecKind::default());
    c.error_lights = 0;
    let out = obj.with_extension("rad");
    c.output = Some(out.clone());
    common::gpu();
    bake::run(&c, &mut |_| {}).expect("bake");
    let baked = Baked::load(&out).unwrap();
    let s = scene::load(obj).unwrap();
    Runtime::new(baked, s, RuntimeOptions::default())
}

/// The bundled Cornell box, copied to a temporary directory and baked once
/// for all the tests of this file (they only read the bake).
fn cornell() -> (Runtime, SceneConfig) {
    let obj = cornell_obj();
    let baked = Baked::load(&obj.with_extension("rad")).unwrap();
    let rt = Runtime::new(baked, scene::load(obj).unwrap(), RuntimeOptions::default());
    let config = scene_config::load(&obj.with_extension("json")).unwrap();
    (rt, config)
}

/// The copied Cornell box's OBJ, its bake beside it (`.rad`), made once.
fn cornell_obj() -> &'static std::path::PathBuf {
    static BAKE: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    BAKE.get_or_init(|| {
        let src = common::bundled("cornell_box");
        let dir = common::temp_dir("gl-cornell");
        for f in ["cornell_box.obj", "cornell_box.mtl", "cornell_box.json"] {
            std::fs::copy(src.with_file_name(f), dir.join(f)).unwrap();
        }
        let obj = dir.join("cornell_box.obj");
        drop(bake(&obj, Resolution::VoxelSize(40.0)));
        obj
    })
}

/// Relative RMS difference `sqrt(Σ (a − b)² / Σ b²)` over three channels.
fn rel_rms(a: &[Vec<f32>; 3], b: &[Vec<f32>; 3]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for c in 0..3 {
        for (x, y) in a[c].iter().zip(&b[c]) {
            num += (*x as f64 - *y as f64).powi(2);
            den += (*y as f64).powi(2);
        }
    }
    (num / den.max(1e-300)).sqrt()
}

/// Nine lights of every kind inside the Cornell box (millimetres): the
/// file's wide spot (a cube of shadow views), narrow spots (one view),
/// points (cubes) and a directional light through the open front.
fn nine_lights(config: &SceneConfig) -> Vec<Light> {
    let mut lights = config.lights.clone();
    let mut rng = SplitMix64::new(12);
    let mut r = |lo: f64, hi: f64| (lo + (hi - lo) * rng.uniform()) as f32;
    for _ in 0..4 {
        lights.push(Light::Spot {
            position: [r(100.0, 450.0), r(350.0, 520.0), r(100.0, 450.0)],
            direction: [r(-0.5, 0.5), -1.0, r(-0.5, 0.5)],
            intensity: [r(2e4, 6e4), r(2e4, 6e4), r(2e4, 6e4)],
            cone_angle_deg: r(20.0, 45.0),
            beam_angle_deg: 10.0,
        });
    }
    for _ in 0..3 {
        lights.push(Light::Point {
            position: [r(100.0, 450.0), r(50.0, 500.0), r(50.0, 500.0)],
            intensity: [r(5e3, 2e4); 3],
        });
    }
    lights.push(Light::Directional {
        direction: [0.2, -0.5, 1.0],
        irradiance: [0.3, 0.3, 0.25],
    });
    lights
}

#[test]
fn gl_direct_light_and_gather_on_patches_match_the_cpu_run_time_with_nine_lights() {
    let ctx = context();
    let gl = &ctx.gl;
    let (mut rt, config) = cornell();
    let lights = nine_lights(&config);
    assert!(lights.len() >= 9);
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).expect("GL renderer");
    let stats = r.frame(gl, &lights, &config.emission).unwrap();
    assert_eq!(stats.lights, lights.len());
    rt.frame(&lights, &config.emission);
    let (d_gl, b0_gl, h_gl) = (r.d(gl), r.b0(gl), r.h(gl));
    for v in d_gl.iter().chain(&b0_gl).chain(&h_gl).flatten() {
        assert!(
            v.is_finite() && *v >= 0.0,
            "a non-finite or negative value {v}"
        );
    }
    let e_d = rel_rms(&d_gl, rt.d());
    let e_h = rel_rms(&h_gl, rt.h());
    // The near-field pass against its CPU reference on the same inputs
    // (GL's D at the lit points): each c_i sums about 9 links × 8 points
    // of f32 products in the same order, so they agree to a few ulps of
    // the largest term; 1e-5 of the largest |c| is far above that and far
    // below any wrong weight or index (each weight is ≥ 1/rays = 2.4e-4).
    let (d_points, m) = r.d_points(gl);
    let weights = rt.near_field_weights(m);
    assert!(
        !weights.is_empty(),
        "the Cornell bake has a near-field correction"
    );
    let c_gl = r.near_field_c(gl).expect("the GL renderer applies it");
    let terms = weights.correction(&radiosity::runtime::direct::reflected_at_points(
        &rt.baked, &d_points, m,
    ));
    let c_cpu = &terms.c;
    let c_max = c_cpu.iter().flatten().fold(0.0f32, |a, v| a.max(v.abs()));
    assert!(c_max > 0.0, "the correction is not zero under these lights");
    for (a, b) in c_gl.iter().flatten().zip(c_cpu.iter().flatten()) {
        assert!(
            (a - b).abs() <= 1e-5 * c_max,
            "near field: GL {a} against CPU {b}"
        );
    }
    // The gather's input B0 + δ + ρ ∘ c: GL's against the CPU's of GL's B0,
    // c and D. δ sums m products per patch like c's links, so the same
    // 1e-5 of the largest term bounds the difference; a pass that left δ
    // out would miss by δ itself, checked to be far above that.
    let gl_terms = radiosity::runtime::near_field::NearTerms {
        c: c_gl.clone(),
        delta: terms.delta.clone(),
    };
    let input = gl_terms.gather_input(&b0_gl, &rt.baked.patches);
    let input_gl = r.near_field_input(gl).expect("the GL renderer applies it");
    let in_max = input.iter().flatten().fold(0.0f32, |a, v| a.max(v.abs()));
    let d_max = terms
        .delta
        .iter()
        .flatten()
        .fold(0.0f32, |a, v| a.max(v.abs()));
    assert!(
        d_max > 1e-3 * in_max,
        "the far weights move some patch's exitance: largest δ {d_max}, input {in_max}"
    );
    for (a, b) in input_gl.iter().flatten().zip(input.iter().flatten()) {
        assert!(
            (a - b).abs() <= 1e-5 * in_max,
            "gather input: GL {a} against CPU {b}"
        );
    }
    // The GL gather of its own input against the CPU gather of the same
    // input: the same decoded entries times the same values, so within
    // twice the f32 summation bound γ_(n+1) Σ_j |T̃_ij x_j| (Higham eq.
    // 3.5; tests/gl_gather.rs), plus one rounding of c added after.
    let (mut h_cpu_of_gl, _, _) = rt.product(&input_gl);
    for ch in 0..3 {
        for j in 0..rt.n() {
            h_cpu_of_gl[ch][j] += c_gl[ch][j];
        }
    }
    let abs: [Vec<f32>; 3] = std::array::from_fn(|c| input_gl[c].iter().map(|v| v.abs()).collect());
    let (magnitude, _, _) = rt.product(&abs);
    let u = f64::from(f32::EPSILON) / 2.0;
    let m = (rt.n() + 1) as f64;
    let gamma = m * u / (1.0 - m * u);
    for ch in 0..3 {
        for j in 0..rt.n() {
            let (a, b) = (f64::from(h_gl[ch][j]), f64::from(h_cpu_of_gl[ch][j]));
            let bound = 2.0 * gamma * 1.001 * f64::from(magnitude[ch][j])
                + 2.0 * u * b.abs()
                + f64::from(f32::MIN_POSITIVE);
            assert!(
                (a - b).abs() <= bound,
                "gather, channel {ch}, patch {j}: GL {a} against CPU {b} (bound {bound:e})"
            );
        }
    }
    let e_gather = rel_rms(&h_gl, &h_cpu_of_gl);
    eprintln!("D rel RMS {e_d:.4}, H rel RMS {e_h:.4}, gather alone {e_gather:.2e}");
    // D: the same shadow rays as the CPU (the next test checks them light
    // by light); each light's irradiance in f32 against the CPU's f64. Shadow maps, which this pass used before,
    // missed by 0.4 % here and by 17 % under Sponza's sun.
    assert!(e_d < 1e-4, "D: relative RMS {e_d} against the CPU's rays");
    // H: the gather of GL's input (bounded above) plus D's rounding.
    assert!(e_h < 1e-3, "H: relative RMS {e_h}");
    r.delete(gl);
}

/// The direct pass's shadow rays (crates/gl/glsl/shadow_ray.glsl: the CPU's BVH,
/// traversal and f64 triangle test on the GPU) against the CPU run time's,
/// each of the nine lights alone, patch by patch. Points and the sun have
/// no `acos`: their D is the CPU's within f32 rounding (measured ≤ 8e-7
/// relative), so the bound 1e-5 of the patch's value plus 1e-7 of the
/// largest D admits no sample point whose ray is answered otherwise (one
/// of 8 points moves its patch's D by an eighth). A spot's profile in its
/// penumbra goes through an angle in f32 (light.glsl's `acos_accurate`,
/// about 1 ulp; llvmpipe's own `acos` had moved it by up to 1.7e-5 of the
/// largest D): measured 4.2e-7 of the largest D, bound 4e-6 of it, far
/// below the eighth of a lit point's share that a ray answered otherwise
/// would move.
#[test]
fn gl_shadow_rays_give_the_cpus_direct_light_light_by_light() {
    let ctx = context();
    let gl = &ctx.gl;
    let (mut rt, config) = cornell();
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).expect("GL renderer");
    let mut blocked = 0usize;
    for (k, light) in nine_lights(&config).into_iter().enumerate() {
        let spot = matches!(light, Light::Spot { .. });
        let one = vec![light];
        r.frame(gl, &one, &config.emission).unwrap();
        rt.frame(&one, &config.emission);
        let d_gl = r.d(gl);
        let d_max = rt.d().iter().flatten().fold(0.0f32, |a, &v| a.max(v));
        let floor = if spot { 4e-6 } else { 1e-7 } * f64::from(d_max);
        let mut worst = 0.0f64;
        for c in 0..3 {
            for (j, (&a, &b)) in d_gl[c].iter().zip(&rt.d()[c]).enumerate() {
                let bound = 1e-5 * f64::from(b.abs()) + floor;
                let diff = f64::from(a - b).abs();
                worst = worst.max(diff / bound);
                assert!(
                    diff <= bound,
                    "light {k} ({}), patch {j}, channel {c}: GL {a} against CPU {b} (bound {bound:e})",
                    if spot { "spot" } else { "point or sun" }
                );
            }
        }
        // Patches lit by nothing but shadowed: the rays did block.
        let unlit = (0..rt.n()).filter(|&j| rt.d()[0][j] == 0.0).count();
        blocked += unlit;
        eprintln!("light {k}: worst |GL − CPU| / bound {worst:.2e}, {unlit} patches unlit");
    }
    assert!(blocked > 0, "some patch is in shadow of some light");
    r.delete(gl);
}

#[test]
fn gl_images_match_the_cpu_renderer_in_every_view() {
    let ctx = context();
    let gl = &ctx.gl;
    let (mut rt, config) = cornell();
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).expect("GL renderer");
    r.frame(gl, &config.lights, &config.emission).unwrap();
    rt.frame(&config.lights, &config.emission);
    let albedo = Albedo::new(&rt.scene);
    let (w, h) = (160, 120);
    for view in [
        View::Final,
        View::Direct,
        View::Indirect,
        View::Patches,
        View::Weights,
    ] {
        let gpu = r
            .render(gl, &config.camera, view, (w, h), &config.emission)
            .unwrap();
        let (cpu, _) = render(&rt, &config, view, w, h, &albedo);
        let (e, coverage) = gpu.difference(&cpu);
        eprintln!("{view:?}: relative RMS {e:.4}, coverage differs on {coverage:.4}");
        assert!(coverage < 0.01, "{view:?}: coverage differs on {coverage}");
        // Measured 0.2 % (final, direct: shadow edges) and 0.7 % (indirect,
        // patches: H's gather rounding, module doc); bound 3 times the
        // larger.
        assert!(e < 0.02, "{view:?}: relative RMS {e}");
    }
    r.delete(gl);
}

#[test]
fn column_skipping_and_unchanged_frames_give_the_image_of_the_full_gather() {
    let ctx = context();
    let gl = &ctx.gl;
    let (rt, config) = cornell();
    // A narrow spot lights a part of the patches: most columns are skipped.
    let spot = Light::Spot {
        position: [278.0, 540.0, 279.5],
        direction: [0.0, -1.0, 0.0],
        intensity: [5e4; 3],
        cone_angle_deg: 15.0,
        beam_angle_deg: 10.0,
    };
    let no_emission: BTreeMap<String, f32> = [("light".to_string(), 0.0)].into();
    let lights = vec![spot];
    let mut skip = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    let mut full = GlRenderer::new(
        gl,
        &rt,
        GlOptions {
            skip_columns: false,
            cache: false,
            ..GlOptions::default()
        },
    )
    .unwrap();
    let a = skip.frame(gl, &lights, &no_emission).unwrap();
    assert!(!a.unchanged);
    full.frame(gl, &lights, &no_emission).unwrap();
    let (h_skip, h_full) = (skip.h(gl), full.h(gl));
    let lit = skip.b0(gl)[0].iter().filter(|&&v| v != 0.0).count();
    assert!(
        lit > 0 && lit < rt.n() / 2,
        "{lit} of {} patches lit",
        rt.n()
    );
    // Skipping changes which tiles the GPU's groups add in which order
    // (the compacted list), not the terms: the two are within twice the
    // f32 summation bound γ_m Σ_j |T̃_ij x_j| of the exact sum (m ≤ n + 1
    // terms; Higham eq. 3.5; tests/gl_gather.rs), plus one rounding of the
    // near-field `c` added after. Σ_j |T̃_ij x_j| is the CPU gather of |x|
    // (every decoded entry is ≥ 0).
    let input = skip.near_field_input(gl).unwrap_or_else(|| skip.b0(gl));
    let abs: [Vec<f32>; 3] = std::array::from_fn(|c| input[c].iter().map(|v| v.abs()).collect());
    let refs = [&abs[0][..], &abs[1][..], &abs[2][..]];
    let every = ActiveColumns::of(refs, rt.baked.matrix.index.tile, true);
    let mut magnitude: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; rt.n()]);
    rt.gather.gather(refs, &every, &mut magnitude);
    let u = f64::from(f32::EPSILON) / 2.0;
    let m = (rt.n() + 1) as f64;
    let gamma = m * u / (1.0 - m * u);
    for c in 0..3 {
        for (i, (x, y)) in h_skip[c].iter().zip(&h_full[c]).enumerate() {
            let bound = 2.0 * gamma * 1.001 * f64::from(magnitude[c][i])
                + 2.0 * u * f64::from(x.abs())
                + f64::from(f32::MIN_POSITIVE);
            assert!(
                (f64::from(*x) - f64::from(*y)).abs() <= bound,
                "channel {c}, patch {i}: skipping gave {x}, every column {y} (bound {bound:e})"
            );
        }
    }
    let cam = &config.camera;
    let img1 = skip
        .render(gl, cam, View::Final, (96, 72), &no_emission)
        .unwrap();
    // The same lights again: nothing runs, and the image is the same.
    let b = skip.frame(gl, &lights, &no_emission).unwrap();
    assert!(b.unchanged);
    let img2 = skip
        .render(gl, cam, View::Final, (96, 72), &no_emission)
        .unwrap();
    let img_full = full
        .render(gl, cam, View::Final, (96, 72), &no_emission)
        .unwrap();
    // Unchanged frames: the same bits. Every column: a pixel's radiance
    // is linear in H (weights ≤ 1 in all), so it differs by at most H's
    // relative bound above, 2 γ_m, plus the shading's own rounding.
    let tolerance = 4.0 * gamma + 1e-6;
    for i in 0..img1.radiance.len() {
        assert_eq!(img1.radiance[i], img2.radiance[i]);
        for c in 0..3 {
            let (a, b) = (img1.radiance[i][c] as f64, img_full.radiance[i][c] as f64);
            assert!(
                (a - b).abs() <= tolerance * a.abs().max(b.abs()) + 1e-30,
                "pixel {i}, channel {c}: {a} with skipping, {b} over every column"
            );
        }
    }
    skip.delete(gl);
    full.delete(gl);
}

/// A frame whose `H` comes from the CPU run time (the viewer's
/// `--patch-light cpu`): the shading reads exactly the CPU's `H`, the
/// indirect view is the GPU frame's within the gather's agreement, and
/// switching between the two kinds of frame recomputes even with the same
/// lights (each leaves other buffers behind).
#[test]
fn a_frame_with_h_from_the_cpu_shades_that_h() {
    let ctx = context();
    let gl = &ctx.gl;
    let (mut rt, config) = cornell();
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    let (lights, scales) = (&config.lights, &config.emission);
    rt.frame(lights, scales);
    let a = r
        .frame_with_h(gl, lights, scales, rt.h(), rt.h_points())
        .unwrap();
    assert!(!a.unchanged && a.views > 0, "{a:?}");
    let uploaded = r.h(gl);
    for c in 0..3 {
        for (x, y) in uploaded[c].iter().zip(&rt.h()[c]) {
            assert_eq!(x.to_bits(), y.to_bits(), "H uploaded is not the CPU's");
        }
    }
    assert!(
        r.frame_with_h(gl, lights, scales, rt.h(), rt.h_points())
            .unwrap()
            .unchanged
    );
    let (w, h) = (96, 72);
    let from_cpu = r
        .render(gl, &config.camera, View::Indirect, (w, h), scales)
        .unwrap();
    // The GPU's own patch light with the same lights: not skipped.
    assert!(!r.frame(gl, lights, scales).unwrap().unchanged);
    let from_gpu = r
        .render(gl, &config.camera, View::Indirect, (w, h), scales)
        .unwrap();
    let (e, coverage) = from_cpu.difference(&from_gpu);
    assert_eq!(coverage, 0.0);
    // The CPU and GPU H differ by their D on the patches (rays against
    // shadow maps) and the gathers' rounding: 0.7 % in the test above;
    // bound 3 times that.
    assert!(
        e < 0.02,
        "indirect view, H from the CPU against the GPU's: {e}"
    );
    let gpu_times = r.pass_times(gl, true);
    assert!(
        !r.frame_with_h(gl, lights, scales, rt.h(), rt.h_points())
            .unwrap()
            .unchanged
    );
    // The GPU times shown are of passes that ran: after the GPU's frame
    // all four; after the CPU's patch light only the shadow maps and the
    // shading, not the GPU's earlier direct light and gather.
    assert!(gpu_times.iter().all(Option::is_some), "{gpu_times:?}");
    r.render(gl, &config.camera, View::Indirect, (w, h), scales)
        .unwrap();
    let cpu_times = r.pass_times(gl, true);
    assert_eq!(
        cpu_times.map(|t| t.is_some()),
        [true, false, false, true],
        "{cpu_times:?}"
    );
    // H of the wrong size is refused.
    let short: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; 3]);
    assert!(r.frame_with_h(gl, &[], scales, &short, None).is_err());
    r.delete(gl);
}

/// More shadow views than the GL's array layers is a clear error naming
/// the count and the limit, checked before allocating; the renderer then
/// draws the earlier lights again, recomputed (the viewer undoes the change
/// that failed).
#[test]
fn too_many_shadow_views_is_a_clear_error_and_the_renderer_goes_on() {
    let ctx = context();
    let gl = &ctx.gl;
    let (rt, config) = cornell();
    let mut r = GlRenderer::new(
        gl,
        &rt,
        GlOptions {
            shadow_resolution: 16,
            ..GlOptions::default()
        },
    )
    .unwrap();
    // SAFETY: a limit query on the current context.
    let max =
        unsafe { glow::HasContext::get_parameter_i32(gl, glow::MAX_ARRAY_TEXTURE_LAYERS) } as usize;
    assert!(
        !r.frame(gl, &config.lights, &config.emission)
            .unwrap()
            .unchanged
    );
    let many: Vec<Light> = (0..max / 6 + 1)
        .map(|i| Light::Point {
            position: [
                100.0 + (i % 20) as f32 * 15.0,
                400.0,
                100.0 + (i / 20) as f32 * 15.0,
            ],
            intensity: [100.0; 3],
        })
        .collect();
    let e = r
        .frame(gl, &many, &config.emission)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("{} views", 6 * many.len()))
            && e.contains(&format!("{max} array layers")),
        "{e}"
    );
    // The lights of the frame before the failure again: the failed frame
    // replaced the lights' buffers, so this one must recompute.
    let ok = r.frame(gl, &config.lights, &config.emission).unwrap();
    assert!(!ok.unchanged && ok.views > 0);
    r.delete(gl);
    // A budget is checked before allocating: 16² maps of 4-byte depth are
    // 1 KiB a view, so 10 KiB hold 10 views; 3 points (18 views) do not,
    // and the renderer goes on with what fits.
    let mut r = GlRenderer::new(
        gl,
        &rt,
        GlOptions {
            shadow_resolution: 16,
            shadow_budget: Some(10 << 10),
            ..GlOptions::default()
        },
    )
    .unwrap();
    let e = r.frame(gl, &many[..3], &config.emission).unwrap_err();
    assert!(
        matches!(
            e,
            GlError::OverBudget {
                bytes: 18432,
                budget: 10240,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("18 views"), "{e}");
    let ok = r.frame(gl, &many[..1], &config.emission).unwrap();
    assert!(!ok.unchanged && ok.views == 6);
    r.delete(gl);
}

#[test]
fn gl_cornell_box_wall_next_to_the_red_wall_receives_more_red() {
    let ctx = context();
    let gl = &ctx.gl;
    let (rt, config) = cornell();
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    r.frame(gl, &config.lights, &config.emission).unwrap();
    let (w, h) = (160, 120);
    let img = r
        .render(gl, &config.camera, View::Indirect, (w, h), &config.emission)
        .unwrap();
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
    let (left, right) = (mean(0.30, 0.36), mean(0.64, 0.70));
    assert!(left[0] > left[1], "next to the red wall: {left:?}");
    assert!(
        left[0] / left[1] > 1.1 * (right[0] / right[1]),
        "red/green next to the red wall {} against next to the green wall {}",
        left[0] / left[1],
        right[0] / right[1]
    );
    r.delete(gl);
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
            ev[v] = if side == 1.0 { -1.0 } else { 1.0 };
            q.push(quad(c, eu, ev, s[u] / 2.0, s[v] / 2.0, [a; 3]));
        }
    }
    q
}

#[test]
fn gl_a_light_outside_a_closed_room_changes_nothing_inside() {
    let ctx = context();
    let gl = &ctx.gl;
    let obj = write_quads("gl-outside", &box_inward([1.0, 0.75, 1.25], 0.6));
    let rt = bake(&obj, Resolution::VoxelSize(0.125));
    let inside = Light::Point {
        position: [0.5, 0.4, 0.6],
        intensity: [2.0; 3],
    };
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    r.frame(gl, std::slice::from_ref(&inside), &BTreeMap::new())
        .unwrap();
    let (d0, h0) = (r.d(gl), r.h(gl));
    assert!(h0[0].iter().any(|&v| v > 0.0));
    let mut rng = SplitMix64::new(3);
    for k in 0..6 {
        let p = [
            3.0 + rng.uniform() as f32,
            -2.0 + 4.0 * rng.uniform() as f32,
            3.0 * rng.uniform() as f32,
        ];
        let outside = if k % 2 == 0 {
            Light::Point {
                position: p,
                intensity: [50.0; 3],
            }
        } else {
            Light::Directional {
                direction: [-p[0], -p[1], -p[2]],
                irradiance: [5.0; 3],
            }
        };
        r.frame(gl, &[inside.clone(), outside], &BTreeMap::new())
            .unwrap();
        let (d, h) = (r.d(gl), r.h(gl));
        for c in 0..3 {
            for j in 0..rt.n() {
                assert_eq!(d[c][j], d0[c][j], "light {k} leaks into patch {j}");
                assert_eq!(h[c][j], h0[c][j], "light {k} leaks into H of patch {j}");
            }
        }
    }
    r.delete(gl);
}

/// The surface map's cut pieces on the GPU (crates/gl/glsl/surface.glsl): a room of
/// single quads split by a thin wall standing on its floor, so the floor,
/// ceiling and side quads are cut where the wall crosses them (the
/// voxelizer's "Pieces cut by a wall"). From the dark room the GPU shows
/// nothing; from the lit room, looking along the wall's foot, the GPU picks
/// the same parts as the CPU (the weights view shows the patches' colours).
#[test]
fn gl_a_thin_wall_on_one_big_floor_keeps_the_dark_room_dark() {
    let ctx = context();
    let gl = &ctx.gl;
    let (x0, x1) = (1.13, 1.14);
    let mut quads = box_inward([2.3, 1.0, 1.0], 0.7);
    quads.push(quad(
        [x0, 0.5, 0.5],
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        0.5,
        0.5,
        [0.7; 3],
    ));
    quads.push(quad(
        [x1, 0.5, 0.5],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        0.5,
        0.5,
        [0.7; 3],
    ));
    let obj = write_quads("gl-wall-on-floor", &quads);
    let mut rt = bake(&obj, Resolution::VoxelSize(0.25));
    assert!(!rt.baked.surface_map.cuts.is_empty(), "no piece was cut");
    let light = Light::Point {
        position: [0.5, 0.6, 0.5],
        intensity: [3.0; 3],
    };
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    r.frame(gl, std::slice::from_ref(&light), &BTreeMap::new())
        .unwrap();
    rt.frame(std::slice::from_ref(&light), &BTreeMap::new());
    let camera = |position: [f32; 3], target: [f32; 3]| scene_config::Camera {
        position,
        target,
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 90.0,
    };
    let dark = camera([2.25, 0.9, 0.5], [x1 as f32, 0.0, 0.5]);
    let img = r
        .render(gl, &dark, View::Indirect, (64, 48), &BTreeMap::new())
        .unwrap();
    assert!(
        img.radiance.iter().all(|p| p.iter().all(|&v| v == 0.0)),
        "the GPU shows light in the dark room"
    );
    let lit = camera([0.1, 0.9, 0.5], [x0 as f32, 0.0, 0.5]);
    let config = SceneConfig {
        objects: Vec::new(),
        sky: None,
        emission: BTreeMap::new(),
        camera: lit.clone(),
        lights: vec![light],
        units: "m".into(),
        description: String::new(),
    };
    let albedo = Albedo::new(&rt.scene);
    for view in [View::Weights, View::Indirect] {
        let gpu = r
            .render(gl, &lit, view, (96, 72), &BTreeMap::new())
            .unwrap();
        let (cpu, _) = render(&rt, &config, view, 96, 72, &albedo);
        let (e, coverage) = gpu.difference(&cpu);
        eprintln!("{view:?}: relative RMS {e:.4}, coverage differs on {coverage:.4}");
        // The bounds of gl_images_match_the_cpu_renderer_in_every_view: a
        // point given the wrong part would show another patch's colour.
        assert!(coverage < 0.01, "{view:?}: coverage differs on {coverage}");
        assert!(e < 0.02, "{view:?}: relative RMS {e}");
    }
    r.delete(gl);
}

#[test]
fn a_broken_shader_names_its_file_and_gives_the_drivers_log() {
    let ctx = context();
    let gl = &ctx.gl;
    let err = compile_program(
        gl,
        &[Stage {
            kind: glow::FRAGMENT_SHADER,
            name: "broken.frag",
            sources: &["out vec4 c;\nvoid main() { c = undefined_thing; }\n"],
        }],
        &[],
    )
    .expect_err("a shader with an undefined name compiles");
    match &err {
        GlError::Shader { name, log } => {
            assert_eq!(name, "broken.frag");
            assert!(log.contains("undefined_thing"), "log: {log}");
        }
        e => panic!("expected a shader error, got {e}"),
    }
    assert!(err.to_string().contains("broken.frag"));
}

#[test]
fn gl_tone_mapping_matches_the_cpus_within_one_step() {
    use glow::HasContext;
    let ctx = context();
    let gl = &ctx.gl;
    let (rt, config) = cornell();
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    r.frame(gl, &config.lights, &config.emission).unwrap();
    let (w, h) = (96, 72);
    let img = r
        .render(gl, &config.camera, View::Final, (w, h), &config.emission)
        .unwrap();
    let (cpu, k) = img.to_srgb8(None);
    let tonemap = radiosity::gl::tonemap::Tonemap::new(gl).unwrap();
    let (texture, size) = r.radiance_texture().unwrap();
    assert_eq!(size, (w, h));
    let mut bytes = vec![0u8; 4 * w * h];
    // SAFETY: an RGBA8 target of w × h on the current context, read back
    // whole.
    unsafe {
        let fbo = gl.create_framebuffer().unwrap();
        let target = gl.create_texture().unwrap();
        gl.bind_texture(glow::TEXTURE_2D, Some(target));
        gl.tex_storage_2d(glow::TEXTURE_2D, 1, glow::RGBA8, w as i32, h as i32);
        gl.bind_framebuffer(glow::FRAMEBUFFER, Some(fbo));
        gl.framebuffer_texture_2d(
            glow::FRAMEBUFFER,
            glow::COLOR_ATTACHMENT0,
            glow::TEXTURE_2D,
            Some(target),
            0,
        );
        tonemap.draw(gl, texture, size, k, Some(fbo));
        gl.bind_framebuffer(glow::READ_FRAMEBUFFER, Some(fbo));
        gl.read_pixels(
            0,
            0,
            w as i32,
            h as i32,
            glow::RGBA,
            glow::UNSIGNED_BYTE,
            glow::PixelPackData::Slice(Some(&mut bytes)),
        );
        gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        gl.delete_framebuffer(fbo);
        gl.delete_texture(target);
    }
    // f32 pow and exp differ between the shader and Rust in the last bits;
    // the 8-bit target rounds to nearest as the CPU does: one step at most.
    let mut worst = 0;
    for y in 0..h {
        for x in 0..w {
            let g = &bytes[4 * ((h - 1 - y) * w + x)..];
            let c = &cpu[3 * (y * w + x)..];
            for ch in 0..3 {
                worst = worst.max((g[ch] as i32 - c[ch] as i32).abs());
            }
        }
    }
    assert!(worst <= 1, "GL tone mapping differs by {worst} / 255");
    tonemap.delete(gl);
    r.delete(gl);
}

/// A closed room whose floor carries a fine texture (a checker of single
/// texels, repeated 16 times across the floor) seen from above its far
/// end, so that the texture is minified about tenfold: with
/// `GlOptions::mipmaps` off, GL filters the albedo as the CPU renderer
/// does (bilinear at full resolution) and the images agree within 2 %;
/// with mipmaps (the viewer's default) GL averages the checker to grey
/// while the CPU samples it, and they differ by far more. So the option
/// is what makes the two back ends' images comparable.
#[test]
fn gl_textured_images_match_the_cpu_renderer_when_both_filter_bilinearly() {
    let ctx = context();
    let gl = &ctx.gl;
    let dir = common::temp_dir("gl-texture");
    // A 64 × 64 checker of single texels, sRGB 40 and 230.
    let img = image::RgbImage::from_fn(64, 64, |x, y| {
        let v = if (x + y) % 2 == 0 { 40 } else { 230 };
        image::Rgb([v, v, v])
    });
    img.save(dir.join("checker.png")).unwrap();
    let (sx, sy, sz) = (2.0f64, 1.5f64, 2.5f64);
    let mut obj = String::from("mtllib scene.mtl\n");
    let mut mtl = String::from(
        "newmtl wall\nKd 0.6 0.6 0.6\n\nnewmtl floor\nKd 0.9 0.9 0.9\nmap_Kd checker.png\n",
    );
    mtl.push('\n');
    let mut v = 0;
    let mut face = |obj: &mut String, corners: [[f64; 3]; 4], material: &str, uv: bool| {
        for c in corners {
            obj.push_str(&format!("v {} {} {}\n", c[0], c[1], c[2]));
        }
        obj.push_str(&format!("usemtl {material}\n"));
        if uv {
            for (a, b) in [(0.0, 0.0), (16.0, 0.0), (16.0, 16.0), (0.0, 16.0)] {
                obj.push_str(&format!("vt {a} {b}\n"));
            }
            obj.push_str(&format!(
                "f {}/{} {}/{} {}/{} {}/{}\n",
                v + 1,
                v + 1,
                v + 2,
                v + 2,
                v + 3,
                v + 3,
                v + 4,
                v + 4
            ));
        } else {
            obj.push_str(&format!("f {} {} {} {}\n", v + 1, v + 2, v + 3, v + 4));
        }
        v += 4;
    };
    // Floor (y = 0, facing up), textured; the other five faces inward.
    face(
        &mut obj,
        [
            [0.0, 0.0, 0.0],
            [0.0, 0.0, sz],
            [sx, 0.0, sz],
            [sx, 0.0, 0.0],
        ],
        "floor",
        true,
    );
    for q in box_inward([sx, sy, sz], 0.6).into_iter().filter(|q| {
        // Every face but the floor (the one whose corners all have y = 0).
        !q.corners.iter().all(|c| c[1] == 0.0)
    }) {
        face(&mut obj, q.corners, "wall", false);
    }
    std::fs::write(dir.join("scene.mtl"), mtl).unwrap();
    let path = dir.join("scene.obj");
    std::fs::write(&path, obj).unwrap();
    let mut rt = bake(&path, Resolution::VoxelSize(0.25));
    let lights = vec![Light::Point {
        position: [1.0, 1.3, 1.25],
        intensity: [3.0; 3],
    }];
    let emission = BTreeMap::new();
    rt.frame(&lights, &emission);
    let config = SceneConfig {
        objects: Vec::new(),
        sky: None,
        camera: scene_config::Camera {
            position: [1.0, 1.4, 2.45],
            target: [1.0, 0.0, 0.3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
        },
        lights: lights.clone(),
        units: "m".into(),
        description: String::new(),
        emission: emission.clone(),
    };
    let albedo = Albedo::new(&rt.scene);
    let (w, h) = (96, 72);
    for mipmaps in [false, true] {
        let mut r = GlRenderer::new(
            gl,
            &rt,
            GlOptions {
                mipmaps,
                ..GlOptions::default()
            },
        )
        .unwrap();
        r.frame(gl, &lights, &emission).unwrap();
        for view in [View::Final, View::Indirect] {
            let gpu = r
                .render(gl, &config.camera, view, (w, h), &emission)
                .unwrap();
            let (cpu, _) = render(&rt, &config, view, w, h, &albedo);
            let (e, coverage) = gpu.difference(&cpu);
            eprintln!("mipmaps {mipmaps}, {view:?}: relative RMS {e:.4}, coverage differs on {coverage:.4}");
            assert!(coverage < 0.01, "{view:?}: coverage differs on {coverage}");
            if mipmaps {
                assert!(
                    e > 0.05,
                    "mipmapped {view:?}: {e}: the texture is not minified"
                );
            } else {
                assert!(e < 0.02, "{view:?}: relative RMS {e}");
            }
        }
        r.delete(gl);
    }
}

/// A point light exactly in a ceiling's plane: the GPU's shadow rays stop
/// short of it as the CPU's do (crates/gl/glsl/shadow_ray.glsl), so the floor is lit
/// and its D is the CPU's patch by patch.
#[test]
fn gl_a_light_in_a_surfaces_plane_lights_the_floor_as_the_cpus() {
    let ctx = context();
    let gl = &ctx.gl;
    let obj = common::floor_under_ceiling("gl-in-plane");
    let mut rt = bake(&obj, Resolution::VoxelSize(0.25));
    let lights = vec![Light::Point {
        position: [0.1, 0.5, -0.15],
        intensity: [1.0; 3],
    }];
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    r.frame(gl, &lights, &BTreeMap::new()).unwrap();
    rt.frame(&lights, &BTreeMap::new());
    let d_gl = r.d(gl);
    let mut floor_patches = 0;
    for (j, p) in rt.baked.patches.iter().enumerate() {
        let (a, b) = (d_gl[0][j], rt.d()[0][j]);
        assert!(
            (a - b).abs() <= 1e-5 * b.abs() + 1e-9,
            "patch {j}: GL {a} against CPU {b}"
        );
        if p.normal[1] > 0.99 {
            floor_patches += 1;
            assert!(b > 0.0, "floor patch {j} is dark");
        }
    }
    assert!(floor_patches > 0);
    r.delete(gl);
}

/// Back sides on some faces only (the winding check, `bake::winding`):
/// the GPU finds a face's twin through the normals buffer's fourth word,
/// so a model with faces wound either way renders as on the CPU, without
/// a pixel seen from behind, from the side of the partition and seat that
/// had no faces (`common::mixed_winding_room`).
#[test]
fn gl_faces_given_a_back_side_render_as_the_cpus() {
    let ctx = context();
    let gl = &ctx.gl;
    let mut rt = bake(
        &common::mixed_winding_room(false),
        Resolution::VoxelSize(0.25),
    );
    assert_eq!(rt.baked.options.twinned.len(), 8);
    let light = Light::Point {
        position: [0.7, 1.6, 1.0],
        intensity: [2.0; 3],
    };
    let config = SceneConfig {
        objects: Vec::new(),
        sky: None,
        emission: BTreeMap::new(),
        camera: scene_config::Camera {
            position: [2.9, 1.0, 0.2],
            target: [1.5, 0.3, 1.2],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 80.0,
        },
        lights: vec![light.clone()],
        units: "m".into(),
        description: String::new(),
    };
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).unwrap();
    r.frame(gl, std::slice::from_ref(&light), &BTreeMap::new())
        .unwrap();
    rt.frame(std::slice::from_ref(&light), &BTreeMap::new());
    let albedo = Albedo::new(&rt.scene);
    for view in [View::Final, View::Indirect] {
        let gpu = r
            .render(gl, &config.camera, view, (160, 120), &config.emission)
            .unwrap();
        let (cpu, stats) = render(&rt, &config, view, 160, 120, &albedo);
        assert_eq!(stats.back_faces, 0);
        let (e, coverage) = gpu.difference(&cpu);
        eprintln!("{view:?}: relative RMS {e:.4}, coverage differs on {coverage:.4}");
        // As gl_images_match_the_cpu_renderer_in_every_view: coverage
        // (pixels seen from behind are uncovered) and 2 %.
        assert!(coverage < 0.01, "{view:?}: coverage differs on {coverage}");
        assert!(e < 0.02, "{view:?}: relative RMS {e}");
    }
    r.delete(gl);
}

/// `examples/gl_embed.rs`: a renderer made in a context the application
/// owns.
#[path = "../examples/gl_embed.rs"]
#[allow(dead_code)]
mod gl_embed;

/// An application that owns its GL context (`examples/gl_embed.rs`): the
/// renderer uploads into it, lights a frame and gives back `H`, the CPU
/// run time's within the bound the full GL frame above is held to (1e-3
/// relative RMS: `D` in f32 against the CPU's f64, then the gather's f32
/// sums).
#[test]
fn a_renderer_in_the_applications_own_context_gives_the_cpus_light() {
    let ctx = Headless::new().expect("a GL context (scripts/setup installs Mesa EGL)");
    let (_, config) = cornell();
    let obj = cornell_obj();
    let c = gl_embed::run(&ctx.gl, &obj.with_extension("rad"), &config.lights).unwrap();
    let e = rel_rms(&c.gpu, &c.cpu);
    assert!(e < 1e-3, "GPU H against the CPU's: relative RMS {e}");
    assert!(
        c.cpu[0].iter().any(|&h| h > 0.0),
        "the light reaches the patches"
    );
}

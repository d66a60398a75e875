//! The near-field correction at the receiver (`radiosity_bakefile::near_field`,
//! "At the receiver"): `H`'s deviation in each patch's face cells, looked
//! up at its sample points, against the path tracer at those points, its
//! zero mean over each receiver, and GL computing it as the CPU does.

// Index loops over channels and patches read several arrays at once.
#![allow(clippy::needless_range_loop)]

mod common;

use common::open_box::unit_box;
use radiosity::bake::voxelize::Resolution;
use radiosity::bakefile::baked::Baked;
use radiosity::bakefile::surface::SAMPLES_PER_PATCH;
use radiosity::core::scene;
use radiosity::core::scene_config::Light;
use radiosity::reference::PathTracer;
use radiosity::runtime::{surface, Runtime, RuntimeOptions};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The unit box open at the top in voxels of 1/2 (each wall two patches
/// high), its floor lit by a sun straight above: the walls get their light
/// from the floor, far more at their foot than at their top, and a wall
/// patch's one `H` is the mean of that profile. Baked once.
fn lit_box() -> (Baked, PathBuf) {
    static BAKE: std::sync::OnceLock<(Baked, PathBuf)> = std::sync::OnceLock::new();
    BAKE.get_or_init(|| {
        let obj = common::write_quads("receiver-box", &unit_box(true));
        let c = common::bake_config(&obj, Resolution::VoxelSize(0.5));
        let out = obj.with_file_name("scene.rad");
        (common::bake_to(c, &out).0, obj)
    })
    .clone()
}

fn sun() -> Light {
    Light::Directional {
        direction: [0.0, -1.0, 0.0],
        irradiance: [10.0, 8.0, 6.0],
    }
}

fn runtime(baked: Baked, obj: &std::path::Path) -> Runtime {
    let mut rt = Runtime::new(baked, scene::load(obj).unwrap(), RuntimeOptions::default());
    rt.frame(&[sun()], &BTreeMap::new());
    rt
}

/// At each wall point, `H_i + Δ_ig` against the path tracer's irradiance
/// at that very point (1,024 paths: its noise is ~3 % of a point's value),
/// and against `H_i` alone, which is what every point of the patch got
/// before. Measured: the deviations take the wall points' relative RMS
/// error from 24.2 % to 10.9 % (the profile's rise towards the floor
/// within each 0.5 m patch); asserted: below half of it, and below 15 %.
#[test]
fn the_deviation_at_the_points_follows_the_path_tracer() {
    let (baked, obj) = lit_box();
    let rt = runtime(baked.clone(), &obj);
    let dev = rt
        .h_points()
        .expect("the bake stores counts by the receiver's cell");
    let h = rt.h();
    let walls: Vec<usize> = (0..baked.patches.len())
        .filter(|&i| baked.patches[i].normal[1].abs() < 0.5)
        .collect();
    assert_eq!(walls.len(), 16, "four walls of 2 × 2 patches");
    let samples = &baked.samples;
    let points: Vec<Vec<([f64; 3], [f64; 3])>> = walls
        .iter()
        .flat_map(|&i| {
            (0..SAMPLES_PER_PATCH).map(move |g| {
                let k = i * SAMPLES_PER_PATCH + g;
                vec![(
                    samples.position[k].map(f64::from),
                    samples.normal[k].map(f64::from),
                )]
            })
        })
        .collect();
    let scene = scene::load(&obj).unwrap();
    let (reference, _): (Vec<_>, Vec<_>) = PathTracer::new(&scene)
        .mean_over_with_sky(&points, &[sun()], 1024, None, 0x5eed)
        .into_iter()
        .unzip();
    let (mut with, mut without, mut norm) = (0.0f64, 0.0f64, 0.0f64);
    for (w, &i) in walls.iter().enumerate() {
        // The deviation where a pixel at each point would take it: the
        // patch's face cells, bilinearly.
        let at: Vec<[f32; 3]> = (0..SAMPLES_PER_PATCH)
            .map(|g| {
                let x = baked.samples.position[i * SAMPLES_PER_PATCH + g];
                let only = [(i as u32, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)];
                surface::at_cells(&only, &baked.surface_map, x, dev)
            })
            .collect();
        for g in 0..SAMPLES_PER_PATCH {
            let r = &reference[w * SAMPLES_PER_PATCH + g].mean;
            for c in 0..3 {
                let plain = f64::from(h[c][i]);
                let shaped = plain + f64::from(at[g][c]);
                with += (shaped - r[c]).powi(2);
                without += (plain - r[c]).powi(2);
                norm += r[c] * r[c];
            }
        }
    }
    let (with, without) = ((with / norm).sqrt(), (without / norm).sqrt());
    eprintln!(
        "wall points against the path tracer: relative RMS {with:.4} with the deviations, \
         {without:.4} with the patch's H alone"
    );
    assert!(with < 0.5 * without, "with {with}, without {without}");
    assert!(with < 0.15, "with {with}");
}

/// The deviations only spread `H` over each receiver: weighted by each
/// cell's rays (the weights the counts define) they sum to 0 in every
/// channel, to f32 rounding of the products (a few ε of the largest term).
#[test]
fn the_deviation_keeps_each_receivers_mean() {
    let (baked, obj) = lit_box();
    let rt = runtime(baked.clone(), &obj);
    let dev = rt.h_points().unwrap();
    let scale = dev.iter().flatten().fold(0.0f32, |a, &v| a.max(v.abs()));
    assert!(scale > 0.0, "no deviation at all");
    for (i, cast) in baked.near_field.cast.iter().enumerate() {
        let total: f64 = cast.iter().map(|&v| f64::from(v)).sum();
        for c in 0..3 {
            let mean: f64 = (0..SAMPLES_PER_PATCH)
                .map(|g| f64::from(cast[g]) * f64::from(dev[c][i * SAMPLES_PER_PATCH + g]))
                .sum::<f64>()
                / total;
            assert!(
                mean.abs() < 64.0 * f64::from(f32::EPSILON) * f64::from(scale),
                "patch {i}, channel {c}: mean deviation {mean} (largest {scale})"
            );
        }
    }
}

/// GL's stage 2 gives the CPU's deviations (the same f32 sums in the same
/// order: measured 6e-8 of the largest, asserted 1e-5), and its indirect
/// image, which
/// adds them per pixel, the CPU renderer's within the GL tests' 2 %.
#[test]
fn gl_spreads_h_over_the_receivers_as_the_cpu_does() {
    use radiosity::gl::context::Headless;
    use radiosity::gl::renderer::{GlOptions, GlRenderer};
    use radiosity::runtime::render::{render, View};
    use radiosity::runtime::texture::Albedo;
    let ctx = Headless::new().unwrap_or_else(|e| {
        panic!("no headless OpenGL 4.5 (EGL on Mesa llvmpipe: run scripts/setup): {e}")
    });
    let gl = &ctx.gl;
    let (baked, obj) = lit_box();
    let rt = runtime(baked, &obj);
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).expect("GL renderer");
    r.frame(gl, &[sun()], &BTreeMap::new()).unwrap();
    let gpu = r.h_points(gl).expect("GL computed the deviations");
    let cpu = rt.h_points().unwrap();
    let scale = cpu.iter().flatten().fold(0.0f32, |a, &v| a.max(v.abs()));
    let worst = (0..3)
        .flat_map(|c| gpu[c].iter().zip(&cpu[c]).map(|(a, b)| (a - b).abs()))
        .fold(0.0f32, f32::max);
    eprintln!("GL deviations against the CPU's: worst {worst:.3e} of {scale:.3e}");
    assert!(worst <= 1e-5 * scale, "worst {worst} of {scale}");
    let config = radiosity::core::scene_config::SceneConfig {
        camera: radiosity::core::scene_config::Camera {
            position: [0.5, 0.6, 0.95],
            target: [0.5, 0.3, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 70.0,
        },
        lights: vec![sun()],
        units: "m".into(),
        description: String::new(),
        emission: BTreeMap::new(),
        sky: None,
        objects: Vec::new(),
    };
    let albedo = Albedo::new(&rt.scene);
    let (w, h) = (96, 72);
    let g = r
        .render(gl, &config.camera, View::Indirect, (w, h), &config.emission)
        .unwrap();
    let (c, _) = render(&rt, &config, View::Indirect, w, h, &albedo);
    let (e, coverage) = g.difference(&c);
    eprintln!("indirect view: GL against the CPU {e:.4} (coverage differs on {coverage:.4})");
    assert!(e < 0.02 && coverage < 0.01, "{e}, {coverage}");
    // The deviations show in that image: without them (a bake without
    // the receiver's counts) it is another.
    let mut plain = rt.baked.clone();
    plain.near_field.cast.clear();
    let flat = runtime(plain, &obj);
    assert!(flat.h_points().is_none());
    let (f, _) = render(&flat, &config, View::Indirect, w, h, &albedo);
    let (moved, _) = f.difference(&c);
    eprintln!("indirect view without the deviations: {moved:.4} from with");
    assert!(
        moved > 0.05,
        "the deviations move the image by {moved} only"
    );
    // And the same image from the CPU's H and deviations uploaded.
    r.frame_with_h(gl, &[sun()], &BTreeMap::new(), rt.h(), rt.h_points())
        .unwrap();
    let u = r
        .render(gl, &config.camera, View::Indirect, (w, h), &config.emission)
        .unwrap();
    let (e2, _) = u.difference(&c);
    assert!(e2 < 0.02, "with the CPU's H and deviations: {e2}");
    r.delete(gl);
}

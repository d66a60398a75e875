//! The sky as a light (issue 43): the baked sky visibility against
//! analytic view factors (a floor in an open box sees the sky through the
//! opening only), a closed room that gets exactly nothing, the sky cells'
//! error against brute force, the sky bounced by the gather, and a bake without
//! sky visibility refused by name; the sun and sky and environment maps
//! against brute force and against the sky they sample, and bad skies
//! refused by name.

// Index loops over channels and patches read several arrays at once.
#![allow(clippy::needless_range_loop)]

mod common;

use common::open_box::{floor_patches, mean_over, to_opening, unit_box};
use common::Quad;
use radiosity::bake::form_factor::FormFactorMethod;
use radiosity::bake::voxelize::Resolution;
use radiosity::bakefile::baked::Baked;
use radiosity::core::scene;
use radiosity::core::sky::Sky;
use radiosity::runtime::{sky, Runtime, RuntimeOptions};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::PathBuf;

/// Bakes `quads` at voxels of 1/8 (the box's sides divide it); the bake
/// and the scene's path.
fn bake(tag: &str, quads: &[Quad], method: FormFactorMethod) -> (Baked, PathBuf) {
    let obj = common::write_quads(tag, quads);
    let mut c = common::bake_config(&obj, Resolution::VoxelSize(0.125));
    c.form_factor.method = method;
    c.near_field_rays = 0;
    let out = obj.with_file_name("scene.rad");
    (common::bake_to(c, &out).0, obj)
}

/// The unit box open at the top, baked once with ray form factors for
/// every test that only reads it: the bake, and the scene's path with
/// `scene.rad` beside it.
fn open_box() -> (Baked, PathBuf) {
    static BAKE: std::sync::OnceLock<(Baked, PathBuf)> = std::sync::OnceLock::new();
    BAKE.get_or_init(|| bake("sky-open-box", &unit_box(true), FormFactorMethod::Rays))
        .clone()
}

/// [`open_box`] baked by the contour method, which casts no rays: no sky
/// visibility.
fn open_box_contour() -> (Baked, PathBuf) {
    static BAKE: std::sync::OnceLock<(Baked, PathBuf)> = std::sync::OnceLock::new();
    BAKE.get_or_init(|| bake("sky-contour", &unit_box(true), FormFactorMethod::Contour))
        .clone()
}

fn runtime((baked, obj): (Baked, PathBuf)) -> Runtime {
    Runtime::new(baked, scene::load(&obj).unwrap(), RuntimeOptions::default())
}

/// A floor in a unit box open at the top, under a uniform sky of radiance
/// L, receives `π L F` where `F` is its view factor to the opening: every
/// other direction meets a wall. The baked transfer comes from the
/// form-factor rays (16,384 per patch, cosine-weighted): its error is
/// that of the fraction of rays that escape, `√(F(1 − F)/N)` at most
/// (quasi-random rays do better), so 4 of those bound it.
#[test]
fn a_floor_in_an_open_box_sees_the_sky_through_the_opening() {
    let (baked, _) = open_box();
    let rays = baked.sky.rays as f64;
    assert_eq!(rays, 16384.0, "the form factors' rays per patch");
    let l = [1.0f32, 2.0, 3.0];
    let d = sky::irradiance(&baked, &Sky::Uniform { radiance: l }).unwrap();
    let floor = floor_patches(&baked);
    assert_eq!(floor.len(), 64, "an 8 × 8 floor");
    let mut worst = 0.0f64;
    for &(i, x, z, h) in &floor {
        let f = mean_over(x, z, h, to_opening);
        let sigma = (f * (1.0 - f) / rays).sqrt();
        for c in 0..3 {
            let want = PI * f64::from(l[c]) * f;
            let got = f64::from(d[c][i]);
            let tol = PI * f64::from(l[c]) * 4.0 * sigma + 1e-6;
            worst = worst.max((got - want).abs() / want);
            assert!(
                (got - want).abs() <= tol,
                "patch {i} at ({x:.3}, {z:.3}): D_sky {got} against π L F = {want} (F = {f:.4})"
            );
        }
    }
    eprintln!("worst relative error of a floor patch's sky irradiance: {worst:.4}");
}

/// A closed room sees no sky: no patch stores a sky cell, and `D_sky`,
/// `B0` and `H` are exactly 0 under the brightest sky (0, not small).
#[test]
fn a_closed_room_gets_nothing_from_the_sky() {
    let baked = bake("sky-closed-box", &unit_box(false), FormFactorMethod::Rays);
    assert!(!baked.0.sky.is_empty());
    assert!(baked.0.sky.values.is_empty());
    let mut rt = runtime(baked);
    rt.set_sky(Some(Sky::Uniform { radiance: [1e6; 3] }))
        .unwrap();
    rt.frame(&[], &BTreeMap::new());
    for c in 0..3 {
        assert!(rt.d()[c].iter().all(|&v| v == 0.0));
        assert!(rt.b0()[c].iter().all(|&v| v == 0.0));
        assert!(rt.h()[c].iter().all(|&v| v == 0.0));
    }
}

/// The sky enters `B0` as `ρ ∘ D_sky` and is bounced by the gather: the
/// walls of the open box get indirect light from the sky-lit floor, `H`
/// is the stored matrix times that `B0` (decoded, f64 sums: the gather's
/// f32 order leaves 1e-4 at most; the gather itself is tested against the
/// decode in `tests/gather.rs`), and taking the sky away gives exactly the
/// dark frame again.
#[test]
fn the_sky_is_bounced_by_the_gather_and_taken_back() {
    let mut rt = runtime(open_box());
    let n = rt.baked.patches.len();
    let t = rt.baked.matrix.decode();
    let sky = Sky::Gradient {
        zenith: [0.3, 0.5, 1.0],
        horizon: [0.8, 0.8, 0.9],
        ground: [0.2, 0.2, 0.2],
    };
    rt.set_sky(Some(sky.clone())).unwrap();
    let s = rt.frame(&[], &BTreeMap::new());
    assert_eq!(s.terms_computed, 2, "emission and the sky");
    let b0 = rt.b0().clone();
    let h = rt.h().clone();
    assert!(h.iter().flatten().any(|&v| v > 0.0));
    // `B0` is ρ ∘ D_sky, and H the decoded matrix (patch order) times it.
    let d = sky::irradiance(&rt.baked, &sky).unwrap();
    for c in 0..3 {
        for (j, p) in rt.baked.patches.iter().enumerate() {
            assert_eq!(b0[c][j], p.albedo[c] * d[c][j]);
        }
        let (mut err, mut norm) = (0.0f64, 0.0f64);
        for r in 0..n {
            let want: f64 = (0..n)
                .map(|k| f64::from(t[c][r * n + k]) * f64::from(b0[c][k]))
                .sum();
            let got = f64::from(h[c][r]);
            err += (got - want).powi(2);
            norm += want * want;
        }
        let rel = (err / norm.max(1e-300)).sqrt();
        assert!(
            rel < 1e-4,
            "channel {c}: H against T̃ B0, relative RMS {rel}"
        );
    }
    // The same sky again is reused; no sky gives the dark frame.
    let s = rt.frame(&[], &BTreeMap::new());
    assert!(s.unchanged);
    rt.set_sky(None).unwrap();
    rt.frame(&[], &BTreeMap::new());
    assert!(rt.h().iter().flatten().all(|&v| v == 0.0));
}

/// The sky cells against brute force: the floor of the open box under a
/// gradient sky, `∫_opening L(ω) cos θ dω` integrated directly over the
/// opening (64 × 64 points per floor point), against `Σ L̄_c T_c` with the
/// baked visibility. What is left is the sky's variation within the cells
/// the opening's edge cuts, and the rays' noise (under 0.3 %: the
/// uniform-sky test). Measured: 1.3 % on this sky, whose red is 5 times
/// brighter at the horizon than at the zenith (band-2 harmonics, the first
/// representation, left 5.7 %). The bound is the measure plus the margin
/// of the noise.
#[test]
fn the_sky_cells_follow_a_gradient_sky_within_a_few_percent_of_brute_force() {
    let (baked, _) = open_box();
    let sky = Sky::Gradient {
        zenith: [0.2, 0.4, 1.0],
        horizon: [1.0, 0.9, 0.7],
        ground: [0.1, 0.1, 0.1],
    };
    let rel = floor_error(&baked, &sky);
    eprintln!(
        "gradient sky (cells) against brute force, floor of the open box: relative RMS {rel:.4}"
    );
    assert!(rel < 0.03, "relative RMS {rel}");
}

/// `∫_opening L(ω) cos θ dω` at the floor point (x, z) of the open box,
/// integrated directly over the opening (64 × 64 points).
fn brute_floor(sky: &Sky, x: f64, z: f64) -> [f64; 3] {
    let k = 64;
    let mut e = [0.0f64; 3];
    for a in 0..k {
        for b in 0..k {
            let ox = (a as f64 + 0.5) / k as f64;
            let oz = (b as f64 + 0.5) / k as f64;
            let v = [ox - x, 1.0, oz - z];
            let r2 = v[0] * v[0] + 1.0 + v[2] * v[2];
            let r = r2.sqrt();
            let dir = v.map(|q| q / r);
            // cos at the floor and at the opening are both v_y / r.
            let w = (1.0 / r) * (1.0 / r) / r2 / (k * k) as f64;
            let l = sky.radiance(dir);
            for c in 0..3 {
                e[c] += l[c] * w;
            }
        }
    }
    e
}

/// The relative RMS over the open box's floor patches and channels of
/// `D_sky` (sky cells, baked visibility) against [`brute_floor`] averaged
/// over each patch.
fn floor_error(baked: &Baked, sky: &Sky) -> f64 {
    let d = sky::irradiance(baked, sky).unwrap();
    let (mut err, mut norm) = (0.0f64, 0.0f64);
    for (i, x, z, h) in floor_patches(baked) {
        for c in 0..3 {
            let want = mean_over(x, z, h, |px, pz| brute_floor(sky, px, pz)[c]);
            let got = f64::from(d[c][i]);
            err += (got - want).powi(2);
            norm += want * want;
        }
    }
    (err / norm).sqrt()
}

/// The relative RMS difference of two skies' `D_sky` over every patch.
fn sky_difference(baked: &Baked, a: &Sky, b: &Sky) -> f64 {
    let (da, db) = (
        sky::irradiance(baked, a).unwrap(),
        sky::irradiance(baked, b).unwrap(),
    );
    let (mut err, mut norm) = (0.0f64, 0.0f64);
    for c in 0..3 {
        for (x, y) in da[c].iter().zip(&db[c]) {
            err += f64::from(x - y).powi(2);
            norm += f64::from(*y).powi(2);
        }
    }
    (err / norm).sqrt()
}

/// The sun and sky (Preetham) through the sky cells against brute force
/// on the open box's floor, the sun at 50° elevation, so that much of the
/// floor sees the circumsolar glow through the opening: the case band-2
/// harmonics could not carry (22 % measured with them, the reason for the
/// cells: `crates/core/src/sky/cells.rs`). Measured: 0.8 %; bound: the
/// measure plus the rays' noise. Its sun is a directional light
/// beside the file's own, travelling away from `sun_direction`, with the
/// model's irradiance times the intensity.
#[test]
fn the_sun_and_sky_is_within_a_few_percent_of_brute_force() {
    use radiosity::core::scene_config::Light;
    use radiosity::core::sky::preetham::Preetham;
    let (baked, _) = open_box();
    let dir = [0.5f32, 0.7, -0.3];
    let sky = Sky::Sunsky {
        sun_direction: dir,
        turbidity: 3.0,
        intensity: 2.0,
    };
    let rel = floor_error(&baked, &sky);
    eprintln!(
        "sun and sky (cells) against brute force, floor of the open box: relative RMS {rel:.4}"
    );
    assert!(rel < 0.03, "relative RMS {rel}");
    let config = looking_at(
        [0.5, 0.5, 0.5],
        [0.5, 0.0, 0.5],
        [0.0, 0.0, 1.0],
        60.0,
        vec![Light::Point {
            position: [0.5, 0.5, 0.5],
            intensity: [1.0; 3],
        }],
        Some(sky),
    );
    let lights = config.frame_lights();
    assert_eq!(lights.len(), 2);
    assert_eq!(lights[0], config.lights[0]);
    let e = Preetham::new(dir.map(f64::from), 3.0).sun_irradiance();
    match lights[1] {
        Light::Directional {
            direction,
            irradiance,
        } => {
            assert_eq!(direction, dir.map(|v| -v));
            for c in 0..3 {
                assert!((f64::from(irradiance[c]) - 2.0 * e[c]).abs() < 1e-5 * e[c]);
            }
        }
        ref l => panic!("{l:?}"),
    }
    // At night there is no sun.
    let mut night = config.clone();
    night.sky = Some(Sky::Sunsky {
        sun_direction: [0.0, -1.0, 0.3],
        turbidity: 3.0,
        intensity: 1.0,
    });
    assert_eq!(night.frame_lights(), night.lights);
}

/// Writes `sky` sampled at the texel centres of a `w × h`
/// latitude-longitude map (the envmap convention) as `path` (.pfm, .hdr
/// or .exr).
fn write_map(sky: &Sky, w: usize, h: usize, path: &std::path::Path) {
    use radiosity::core::sky::envmap::direction;
    let texels: Vec<[f32; 3]> = (0..w * h)
        .map(|k| {
            let (u, v) = (
                ((k % w) as f64 + 0.5) / w as f64,
                ((k / w) as f64 + 0.5) / h as f64,
            );
            sky.radiance(direction(u, v)).map(|x| x as f32)
        })
        .collect();
    match path.extension().and_then(|e| e.to_str()) {
        Some("pfm") => radiosity::runtime::tonemap::write_pfm(path, w, h, &texels).unwrap(),
        _ => {
            let img = image::Rgb32FImage::from_fn(w as u32, h as u32, |x, y| {
                image::Rgb(texels[y as usize * w + x as usize])
            });
            image::DynamicImage::ImageRgb32F(img).save(path).unwrap();
        }
    }
}

/// An environment map lights as the sky it samples: the sun and sky
/// written as a 256 × 128 map in each format, read through the
/// camera-and-lights file (the path relative to it) with intensity 2, gives
/// the `D_sky` of the sun and sky of intensity 2 on every patch, to the
/// map's sampling (and the 8-bit mantissa of .hdr's RGBE). Measured: .pfm
/// and .exr 0.07 %, .hdr 0.33 %; bound 1 %. And turned by 90° it lights as the sky
/// whose sun is turned by 90° about `+y`: the map and the sky agree on the
/// rotation's sense.
#[test]
fn an_environment_map_lights_as_the_sky_it_samples() {
    use radiosity::core::scene_config::SceneConfig;
    let (baked, obj) = open_box();
    let dir = obj.parent().unwrap().to_path_buf();
    let sun = [0.6f32, 0.5, -0.2];
    let sunsky = |d: [f32; 3], k: f32| Sky::Sunsky {
        sun_direction: d,
        turbidity: 3.0,
        intensity: k,
    };
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    for ext in ["pfm", "exr", "hdr"] {
        write_map(
            &sunsky(sun, 1.0),
            256,
            128,
            &dir.join(format!("maps/sky.{ext}")),
        );
        for rotation in [0.0f32, 90.0] {
            let json = format!(
                r#"{{"camera": {{"position": [0.5, 0.5, 0.5], "target": [0.5, 0.0, 0.5],
                    "up": [0.0, 0.0, 1.0], "fov_y_deg": 60.0}},
                   "lights": [], "units": "m",
                   "sky": {{"type": "envmap", "file": "maps/sky.{ext}", "intensity": 2.0,
                            "rotation_deg": {rotation}}}}}"#
            );
            let path = dir.join("envmap.json");
            let config = SceneConfig::from_json(&json, &path).unwrap();
            let map_sky = config.sky.unwrap();
            assert!(map_sky.is_ready());
            // R_y(a) (x, y, z) = (c x + s z, y, −s x + c z).
            let (s, c) = rotation.to_radians().sin_cos();
            let turned = [c * sun[0] + s * sun[2], sun[1], -s * sun[0] + c * sun[2]];
            let rel = sky_difference(&baked, &map_sky, &sunsky(turned, 2.0));
            eprintln!("envmap .{ext} turned {rotation}° against its sky: relative RMS {rel:.4}");
            assert!(rel < 0.01, ".{ext} {rotation}: {rel}");
        }
    }
    // The test can fail: the map turned the other way is far off.
    let (s, c) = (-90f32).to_radians().sin_cos();
    let wrong = [c * sun[0] + s * sun[2], sun[1], -s * sun[0] + c * sun[2]];
    let json = r#"{"camera": {"position": [0.5, 0.5, 0.5], "target": [0.5, 0.0, 0.5],
        "up": [0.0, 0.0, 1.0], "fov_y_deg": 60.0}, "lights": [], "units": "m",
        "sky": {"type": "envmap", "file": "maps/sky.pfm", "intensity": 2.0, "rotation_deg": 90}}"#;
    let config = SceneConfig::from_json(json, &dir.join("envmap.json")).unwrap();
    let rel = sky_difference(&baked, config.sky.as_ref().unwrap(), &sunsky(wrong, 2.0));
    assert!(rel > 0.05, "{rel}");
}

/// Bad skies are refused naming the field, the file or the pixel: a
/// missing map, an unknown extension, a negative texel, a turbidity
/// outside the model's range, a sun direction of zeros, light beyond what
/// the frame's f32 sums hold.
#[test]
fn bad_skies_are_refused_by_name() {
    use radiosity::core::scene_config::SceneConfig;
    let dir = common::temp_dir("sky-bad");
    let path = dir.join("bad.json");
    let with_sky = |sky: &str| {
        format!(
            r#"{{"camera": {{"position": [0.5, 0.5, 0.5], "target": [0.5, 0.0, 0.5],
                "up": [0.0, 0.0, 1.0], "fov_y_deg": 60.0}},
               "lights": [], "units": "m", "sky": {sky}}}"#
        )
    };
    let err = |sky: &str| {
        SceneConfig::from_json(&with_sky(sky), &path)
            .unwrap_err()
            .to_string()
    };
    let e = err(r#"{"type": "envmap", "file": "nowhere.hdr"}"#);
    assert!(e.contains("nowhere.hdr") && e.contains("bad.json"), "{e}");
    std::fs::write(dir.join("sky.png"), b"not a map").unwrap();
    let e = err(r#"{"type": "envmap", "file": "sky.png"}"#);
    assert!(
        e.contains("sky.png") && e.contains(".hdr, .exr or .pfm"),
        "{e}"
    );
    let mut texels = vec![[1.0f32; 3]; 8];
    texels[5] = [1.0, -0.5, 1.0];
    radiosity::runtime::tonemap::write_pfm(&dir.join("neg.pfm"), 4, 2, &texels).unwrap();
    let e = err(r#"{"type": "envmap", "file": "neg.pfm"}"#);
    assert!(
        e.contains("neg.pfm") && e.contains("(1, 1)") && e.contains("-0.5"),
        "{e}"
    );
    std::fs::write(dir.join("cut.pfm"), b"PF\n4 2\n-1.0\n\0\0\0\0").unwrap();
    let e = err(r#"{"type": "envmap", "file": "cut.pfm"}"#);
    assert!(e.contains("cut.pfm") && e.contains("needs 96"), "{e}");
    let e = err(r#"{"type": "sunsky", "sun_direction": [0, 1, 0], "turbidity": 20}"#);
    assert!(e.contains("sky.turbidity") && e.contains("20"), "{e}");
    let e = err(r#"{"type": "sunsky", "sun_direction": [0, 0, 0], "turbidity": 3}"#);
    assert!(e.contains("sky.sun_direction"), "{e}");
    let e = err(r#"{"type": "envmap", "file": "neg.pfm", "intensity": -1}"#);
    assert!(e.contains("sky.intensity"), "{e}");
    // Light beyond what the frame's f32 sums hold: a radiance, a sun and
    // sky's intensity, a map's brightest texel times its intensity.
    let e = err(r#"{"type": "uniform", "radiance": [3e38, 0, 0]}"#);
    assert!(e.contains("sky.radiance") && e.contains("1e35"), "{e}");
    let e =
        err(r#"{"type": "sunsky", "sun_direction": [0, 1, 0], "turbidity": 3, "intensity": 1e36}"#);
    assert!(e.contains("sky.intensity"), "{e}");
    radiosity::runtime::tonemap::write_pfm(&dir.join("bright.pfm"), 2, 1, &[[1e30; 3], [1.0; 3]])
        .unwrap();
    let e = err(r#"{"type": "envmap", "file": "bright.pfm", "intensity": 1e6}"#);
    assert!(
        e.contains("sky.intensity") && e.contains("brightest"),
        "{e}"
    );
    assert!(SceneConfig::from_json(
        &with_sky(r#"{"type": "envmap", "file": "bright.pfm", "intensity": 1}"#),
        &path
    )
    .is_ok());
}

/// A bake whose form factors cast no rays (the contour method) has no sky
/// visibility: the sky is refused naming the file, and the frame stays as
/// it was.
#[test]
fn a_bake_without_sky_visibility_says_so() {
    let baked = open_box_contour();
    assert!(baked.0.sky.is_empty());
    let file = baked.0.file.clone();
    let uniform = Sky::Uniform { radiance: [1.0; 3] };
    let e = sky::irradiance(&baked.0, &uniform).unwrap_err();
    assert!(e.to_string().contains(&file), "{e}");
    let mut rt = runtime(baked);
    let e = rt.set_sky(Some(uniform)).unwrap_err();
    assert!(e.to_string().contains("bake"), "{e}");
    assert!(rt.sky().is_none());
}

/// Direct sky on pixels: the patches' `D_sky` through the surface map (the
/// weights `H` takes), so visibility at patch resolution. Measured against
/// the analytic point view factor on the open box's floor (a 32 × 32 grid
/// of points, through the renderer's own lookup): the error this choice
/// leaves is largest by the walls, where the opening's view factor changes
/// fastest within a patch. Measured: relative RMS 1.6 %, worst point
/// 10 % (in a corner). Bound: the RMS plus margin.
#[test]
fn direct_sky_on_pixels_follows_the_opening_at_patch_resolution() {
    use radiosity::runtime::surface;
    let mut rt = runtime(open_box());
    let l = [1.0f32, 2.0, 3.0];
    rt.set_sky(Some(Sky::Uniform { radiance: l })).unwrap();
    rt.frame(&[], &BTreeMap::new());
    let d = rt.d_sky().expect("a sky term").clone();
    // The floor is the third quad: triangles 4 and 5.
    let floor = [4usize, 5];
    let k = 32;
    let (mut err, mut norm, mut worst) = (0.0f64, 0.0f64, 0.0f64);
    for a in 0..k {
        for b in 0..k {
            let (x, z) = ((a as f64 + 0.5) / k as f64, (b as f64 + 0.5) / k as f64);
            let p = [x as f32, 0.0, z as f32];
            let (w, how) = floor
                .iter()
                .map(|&t| surface::weights(&rt.baked.surface_map, t, p))
                .find(|(_, how)| *how == surface::Lookup::Piece)
                .expect("a floor point lies on a floor triangle");
            assert_eq!(how, surface::Lookup::Piece);
            let got = surface::apply(&w, &d);
            let f = to_opening(x, z);
            for c in 0..3 {
                let want = PI * f64::from(l[c]) * f;
                let e = f64::from(got[c]) - want;
                err += e * e;
                norm += want * want;
                worst = worst.max(e.abs() / want);
            }
        }
    }
    let rel = (err / norm).sqrt();
    eprintln!("direct sky on floor pixels against the point view factor: relative RMS {rel:.4}, worst {worst:.4}");
    assert!(rel < 0.05, "relative RMS {rel}");
}

/// Where a camera ray leaves the scene the image shows the sky: from the
/// middle of the open box looking up through the opening (60° field, the
/// opening subtends 90°), every pixel is the sky's radiance exactly, and
/// none counts as covered (so the sky does not set the exposure).
#[test]
fn the_sky_is_seen_where_camera_rays_leave_the_scene() {
    use radiosity::runtime::render::{render, View};
    use radiosity::runtime::texture::Albedo;
    let mut rt = runtime(open_box());
    let l = [0.25f32, 0.5, 1.0];
    let sky = Sky::Uniform { radiance: l };
    rt.set_sky(Some(sky.clone())).unwrap();
    rt.frame(&[], &BTreeMap::new());
    let config = looking_at(
        [0.5, 0.5, 0.5],
        [0.5, 2.0, 0.5],
        [0.0, 0.0, 1.0],
        60.0,
        Vec::new(),
        Some(sky),
    );
    let albedo = Albedo::new(&rt.scene);
    for view in [View::Final, View::Direct] {
        let (img, _) = render(&rt, &config, view, 32, 24, &albedo);
        assert!(img.covered.iter().all(|&c| !c));
        assert!(img.radiance.iter().all(|&p| p == l), "{view:?}");
    }
    // The indirect view has no sky in it.
    let (img, _) = render(&rt, &config, View::Indirect, 32, 24, &albedo);
    assert!(img.radiance.iter().all(|&p| p == [0.0; 3]));
}

/// `radiosity render` takes the sky from the camera-and-lights file: from
/// inside the open box looking up through the opening, the linear image
/// (`--hdr`) is the sky's radiance in every pixel. A bake without sky
/// visibility renders with a warning that names it, and a black sky.
#[test]
fn render_takes_the_sky_from_the_camera_and_lights_file() {
    use radiosity::mitsuba::reference::read_pfm;
    use std::process::Command;
    let run = |rad: &std::path::Path, json: &std::path::Path, tag: &str| {
        let dir = common::temp_dir(tag);
        let (png, pfm) = (dir.join("out.png"), dir.join("out.pfm"));
        let o = Command::new(env!("CARGO_BIN_EXE_radiosity"))
            .args(["render", rad.to_str().unwrap(), "--backend", "cpu"])
            .args(["--camera-lights", json.to_str().unwrap()])
            .args(["--width", "32", "--height", "24", "--view", "direct"])
            .args(["-o", png.to_str().unwrap(), "--hdr", pfm.to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        (read_pfm(&pfm).unwrap(), err)
    };
    let json_text = r#"{
        "camera": {"position": [0.5, 0.5, 0.5], "target": [0.5, 2.0, 0.5],
                   "up": [0.0, 0.0, 1.0], "fov_y_deg": 60.0},
        "lights": [], "units": "m",
        "sky": {"type": "uniform", "radiance": [0.25, 0.5, 1.0]}
    }"#;
    let (_, obj) = open_box();
    let json = obj.with_file_name("sky.json");
    std::fs::write(&json, json_text).unwrap();
    let (img, err) = run(&obj.with_file_name("scene.rad"), &json, "sky-cli-out");
    assert!(!err.contains("warning"), "{err}");
    assert_eq!(img.pixels.len(), 32 * 24);
    assert!(
        img.pixels.iter().all(|&p| p == [0.25, 0.5, 1.0]),
        "{:?}",
        img.pixels[0]
    );
    // Without sky visibility: said, and drawn without the sky.
    let (_, obj) = open_box_contour();
    let json = obj.with_file_name("sky.json");
    std::fs::write(&json, json_text).unwrap();
    let (img, err) = run(&obj.with_file_name("scene.rad"), &json, "sky-cli-old-out");
    assert!(
        err.contains("warning") && err.contains("no sky visibility") && err.contains("scene.rad"),
        "{err}"
    );
    assert!(img.pixels.iter().all(|&p| p == [0.0; 3]));
}

/// The sky on GL (crates/gl/src/sky.rs) against the CPU renderer: from
/// inside the open box looking up at a wall and out through the opening,
/// under a sun and sky with its sun, every view. The patches' `B0` and `H`
/// carry the sky's term on both; the pixels add `D_sky` through the
/// surface map; the background is a 1024 × 512 table on GL and exact on
/// the CPU. Measured on llvmpipe: final 0.4 %, direct 0.5 %, indirect
/// under 0.01 % relative RMS (shadow-map edges of the sun, the table's
/// bilinear lookup and the gather's f32 order); bound 2 %, as the Cornell box's
/// images (tests/gl_render.rs). Without the sky GL's image is far off, and
/// a bake without sky visibility is refused on GL as on the CPU.
#[test]
fn gl_draws_the_sky_as_the_cpu_renderer_does() {
    use radiosity::gl::context::Headless;
    use radiosity::gl::renderer::{GlOptions, GlRenderer};
    use radiosity::runtime::render::{render, View};
    use radiosity::runtime::texture::Albedo;
    let ctx = Headless::new().unwrap_or_else(|e| {
        panic!("no headless OpenGL 4.5 (EGL on Mesa llvmpipe: run scripts/setup): {e}")
    });
    let gl = &ctx.gl;
    let mut rt = runtime(open_box());
    let sky = Sky::Sunsky {
        sun_direction: [0.4, 1.0, 0.5],
        turbidity: 3.0,
        intensity: 0.02,
    };
    let config = looking_at(
        [0.5, 0.25, 0.15],
        [0.5, 1.3, 0.95],
        [0.0, 1.0, 0.0],
        70.0,
        Vec::new(),
        Some(sky.clone()),
    );
    let lights = config.frame_lights();
    assert_eq!(lights.len(), 1, "the sky's sun");
    rt.set_sky(Some(sky.clone())).unwrap();
    rt.frame(&lights, &config.emission);
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).expect("GL renderer");
    r.set_sky(gl, &rt, Some(&sky)).unwrap();
    r.frame(gl, &lights, &config.emission).unwrap();
    let albedo = Albedo::new(&rt.scene);
    let (w, h) = (96, 72);
    for view in [View::Final, View::Direct, View::Indirect] {
        let gpu = r
            .render(gl, &config.camera, view, (w, h), &config.emission)
            .unwrap();
        let (cpu, _) = render(&rt, &config, view, w, h, &albedo);
        let (e, coverage) = gpu.difference(&cpu);
        eprintln!("GL sky, {view:?}: relative RMS {e:.4}, coverage differs on {coverage:.4}");
        assert!(coverage < 0.01, "{view:?}: coverage differs on {coverage}");
        assert!(e < 0.02, "{view:?}: relative RMS {e}");
        if view == View::Final {
            let sky_pixels = gpu.covered.iter().filter(|&&c| !c).count();
            assert!(sky_pixels > w * h / 10, "the sky is in view: {sky_pixels}");
        }
    }
    // Without the sky (and its sun) the image is far from the CPU's.
    let cpu = render(&rt, &config, View::Final, w, h, &albedo).0;
    r.set_sky(gl, &rt, None).unwrap();
    r.frame(gl, &[], &config.emission).unwrap();
    let dark = r
        .render(gl, &config.camera, View::Final, (w, h), &config.emission)
        .unwrap();
    assert!(dark.difference(&cpu).0 > 0.5);
    r.delete(gl);
    // A bake without sky visibility: refused on GL too.
    let old = runtime(bake(
        "sky-gl-old",
        &unit_box(true),
        FormFactorMethod::Contour,
    ));
    let mut r = GlRenderer::new(gl, &old, GlOptions::default()).unwrap();
    assert!(r.set_sky(gl, &old, Some(&sky)).is_err());
    assert!(r.sky().is_none());
    r.delete(gl);
}

/// `bench accuracy` under a sky: the open box under a sun and sky, each
/// patch's `D_sky` (sky cells) and `H` (the sky and its sun bounced)
/// against the path tracer, which sees the sky where its paths leave the
/// box. Measured (256 paths from 16 points a patch): `D_sky` 3.3 % relative
/// RMS of which the reference's noise is 2.9 %, `H` 2.2 % (noise 1.5 %).
/// Bounds: 5 % (the noise and a margin) and 10 %, the Cornell box's bound
/// for `H` (tests/accuracy.rs). Without the
/// sky in the reference, `D_sky` would be compared with 0: the sky's path
/// term is what the figures check.
#[test]
fn bench_accuracy_compares_the_sky_with_the_path_tracer() {
    let (_, obj) = open_box();
    let config = looking_at(
        [0.5, 0.5, 0.5],
        [0.5, 0.0, 0.5],
        [0.0, 0.0, 1.0],
        60.0,
        Vec::new(),
        Some(Sky::Sunsky {
            sun_direction: [0.3, 1.0, 0.2],
            turbidity: 3.0,
            intensity: 0.1,
        }),
    );
    let (report, text) = radiosity::bench::accuracy::run(
        &obj.with_file_name("scene.rad"),
        &config,
        256,
        16,
        None,
        None,
        true,
    )
    .unwrap();
    eprintln!("{text}");
    let sky = report.sky.expect("a sky comparison");
    assert!(sky.rel_rms < 0.05, "{sky:?}");
    assert!(report.total.rel_rms < 0.10, "{:?}", report.total);
}

/// A camera-and-lights file in metres: the camera at `position` looking at
/// `target` (`up`, `fov` degrees), `lights` and `sky`.
fn looking_at(
    position: [f32; 3],
    target: [f32; 3],
    up: [f32; 3],
    fov: f32,
    lights: Vec<radiosity::core::scene_config::Light>,
    sky: Option<Sky>,
) -> radiosity::core::scene_config::SceneConfig {
    use radiosity::core::scene_config::{Camera, SceneConfig};
    SceneConfig {
        objects: Vec::new(),
        camera: Camera {
            position,
            target,
            up,
            fov_y_deg: fov,
        },
        lights,
        units: "m".into(),
        description: String::new(),
        emission: BTreeMap::new(),
        sky,
    }
}

/// The library refuses a sky it cannot draw as it is, saying which: a map
/// whose file was never read (it would light nothing), a sky out of range
/// (a NaN radiance would reach every pixel); the sky stays as it was.
#[test]
fn the_run_time_refuses_a_map_not_read_and_an_invalid_sky() {
    use radiosity::runtime::sky::SkyError;
    let mut rt = runtime(open_box());
    let unread = Sky::Envmap {
        file: "sky.hdr".into(),
        intensity: 1.0,
        rotation_deg: 0.0,
        map: None,
    };
    let e = rt.set_sky(Some(unread)).unwrap_err();
    assert!(matches!(e, SkyError::NotRead { .. }), "{e}");
    assert!(e.to_string().contains("sky.hdr"), "{e}");
    let nan = Sky::Uniform {
        radiance: [f32::NAN, 0.0, 0.0],
    };
    let e = rt.set_sky(Some(nan)).unwrap_err();
    assert!(e.to_string().contains("sky.radiance"), "{e}");
    assert!(rt.sky().is_none());
}

//! The viewer's window (`radiosity view`) under Xvfb, run as a user runs
//! it: scripted frames and a screenshot that must show what the headless
//! GL renderer draws from the same camera and lights; keys pressed in the
//! window (`--keys`) editing, saving and taking back lights; without a
//! display, a clear error, and the headless fallback of the README's main
//! command.
//! Xvfb comes from scripts/setup; a machine without `xvfb-run` fails here
//! with a message saying so.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The bundled Cornell box copied to a temporary directory (its bake cache
/// goes there too): the OBJ and the directory.
fn cornell(tag: &str) -> (PathBuf, PathBuf) {
    let obj = common::bundled_copy("cornell_box", tag);
    let dir = obj.parent().unwrap().to_path_buf();
    (obj, dir)
}

/// The small window and bake of the key tests: 160 × 120, 800 patches,
/// shadow maps of 512².
const SMALL: [&str; 8] = [
    "--width",
    "160",
    "--height",
    "120",
    "--patches",
    "800",
    "--shadow-resolution",
    "512",
];

fn radiosity(dir: &Path, args: &[&str], display: bool) -> Output {
    let exe = env!("CARGO_BIN_EXE_radiosity");
    let mut c = if display {
        let mut c = Command::new("xvfb-run");
        // -noreset: an X server that resets when its last client leaves
        // signals xvfb-run (SIGUSR1) just as xvfb-run removes its
        // temporary directory, which then fails now and again with exit
        // status 5 ("problem while cleaning up temporary directory"), seen
        // when the viewer quits at once (Esc).
        c.args(["-a", "-s", "-screen 0 640x480x24 -noreset", exe]);
        c
    } else {
        Command::new(exe)
    };
    c.args(args)
        .env("RADIOSITY_CACHE_DIR", dir.join("cache"))
        .env_remove("WAYLAND_DISPLAY");
    if !display {
        c.env_remove("DISPLAY");
    }
    c.output().unwrap_or_else(|e| {
        panic!("cannot run {exe} (display {display}): {e} (xvfb-run: run scripts/setup)")
    })
}

/// The largest and the mean absolute difference of two images' channels,
/// in 1/255.
fn difference(a: &image::RgbImage, b: &image::RgbImage) -> (i32, f64) {
    assert_eq!(a.dimensions(), b.dimensions());
    let d: Vec<i32> = a
        .pixels()
        .zip(b.pixels())
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] as i32 - q[c] as i32).abs()))
        .collect();
    (
        *d.iter().max().unwrap(),
        d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64,
    )
}

/// [`radiosity`] with its arguments given in parts (a command's own, then
/// shared ones such as the image size), concatenated.
fn run(dir: &Path, parts: &[&[&str]], display: bool) -> Output {
    radiosity(dir, &parts.concat(), display)
}

/// `obj` rendered headless on GL into `png` at `size`, and the exposure the
/// renderer picked for it: the window's later frames keep one exposure, so
/// a test gives the viewer this one to compare both sides.
fn gl_render_exposure(dir: &Path, obj: &str, png: &Path, size: &[&str]) -> String {
    let o = run(
        dir,
        &[
            &[
                "render",
                obj,
                "--backend",
                "gl",
                "-o",
                png.to_str().unwrap(),
            ][..],
            size,
        ],
        false,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    common::printed_exposure(&err)
}

/// The viewer under Xvfb for `frames` frames with `keys` pressed, at a
/// fixed `exposure`, the GL's own patch light (as `render --backend gl`
/// computes it: the CPU's differs by a few 1/255 here,
/// `patch_light_on_the_cpu_shows_what_the_gpu_computes`), saving to
/// `saved` (F5) and the last frame to `shot.png`.
fn view_with_keys(
    dir: &Path,
    obj: &str,
    frames: usize,
    keys: &str,
    saved: &Path,
    exposure: &str,
) -> Output {
    let shot = dir.join("shot.png");
    let frames = frames.to_string();
    run(
        dir,
        &[
            &["view", obj, "--frames", &frames, "--keys", keys][..],
            &["--patch-light", "gpu", "--exposure", exposure][..],
            &["--save-to", saved.to_str().unwrap()][..],
            &["--screenshot", shot.to_str().unwrap()][..],
            &SMALL[..],
        ],
        true,
    )
}

/// The camera and lights the window saved (`saved`), drawn headless at
/// `exposure` into `saved.png`, against the window's screenshot
/// (`shot.png`): equal up to two GL contexts' rounding (1/255). Returns
/// the screenshot.
fn window_is_the_saved_file(
    dir: &Path,
    obj: &str,
    saved: &Path,
    exposure: &str,
) -> image::RgbImage {
    let out = dir.join("saved.png");
    let o = run(
        dir,
        &[
            &["render", obj, "--backend", "gl", "--exposure", exposure][..],
            &["--camera-lights", saved.to_str().unwrap()][..],
            &["-o", out.to_str().unwrap()][..],
            &SMALL[..],
        ],
        false,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (shot, drawn) = (rgb(&dir.join("shot.png")), rgb(&out));
    let (worst, mean) = difference(&shot, &drawn);
    assert!(
        worst <= 1,
        "the window's last frame differs by {worst} / 255 (mean {mean})"
    );
    shot
}

fn rgb(path: &Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
        .to_rgb8()
}

#[test]
fn scripted_frames_in_a_window_show_what_the_headless_renderer_draws() {
    let (obj, dir) = cornell("viewer-window");
    let obj = obj.to_str().unwrap();
    let shot = dir.join("shot.png");
    let size = ["--width", "160", "--height", "120", "--patches", "800"];
    let o = run(
        &dir,
        &[
            &[
                "view",
                obj,
                "--frames",
                "4",
                "--screenshot",
                shot.to_str().unwrap(),
                // Exact gathers, as the headless GL renderer's: on
                // llvmpipe the viewer's patch light runs on the CPU, whose
                // default culling of negligible columns moves a pixel by
                // 2 / 255 here (`docs/measurements/runtime-cpu.md`, "Culling negligible columns").
                "--cull",
                "0",
            ],
            &size[..],
        ],
        true,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "view under Xvfb failed: {err}");
    assert!(err.contains("4 frames"), "{err}");
    let headless = dir.join("headless.png");
    let o = run(
        &dir,
        &[
            &[
                "render",
                obj,
                "--backend",
                "gl",
                "-o",
                headless.to_str().unwrap(),
            ],
            &size[..],
        ],
        false,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (rgb(&shot), rgb(&headless));
    assert_eq!(a.dimensions(), (160, 120));
    assert_eq!(a.dimensions(), b.dimensions());
    // The same GL passes, camera, lights and automatic exposure: the images
    // may differ only where two GL contexts round differently (none seen).
    let (worst, _) = difference(&a, &b);
    assert!(
        worst <= 1,
        "the window's screenshot differs by {worst} / 255"
    );
    // And the picture is not black: the box is lit.
    let mean: f64 = a.pixels().map(|p| p[0] as f64).sum::<f64>() / (160.0 * 120.0);
    assert!(mean > 20.0, "mean red {mean}");
}

/// `--patch-light cpu`: the CPU run time's `H` in the GPU's shading gives
/// the picture of the GPU's own patch light, up to how the two compute
/// `D` on the patches (shadow rays against shadow maps); `auto` times
/// both and keeps the faster (on llvmpipe, where the GL gather is two
/// orders of magnitude slower than the CPU's, the CPU).
#[test]
fn patch_light_on_the_cpu_shows_what_the_gpu_computes() {
    let (obj, dir) = cornell("viewer-patch-light");
    let obj = obj.to_str().unwrap();
    let size = ["--width", "160", "--height", "120", "--patches", "800"];
    let shot = |mode: &str| {
        let png = dir.join(format!("{mode}.png"));
        let o = run(
            &dir,
            &[
                &[
                    "view",
                    obj,
                    "--frames",
                    "3",
                    "--patch-light",
                    mode,
                    "--screenshot",
                    png.to_str().unwrap(),
                ],
                &size[..],
            ],
            true,
        );
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "--patch-light {mode}: {err}");
        (rgb(&png), err)
    };
    // The last GPU times name the passes that ran on the GPU: all four, or
    // with the CPU's patch light the shadow maps and the shading only.
    let times = |e: &str| e.lines().last().unwrap_or("").to_string();
    let (gpu, e) = shot("gpu");
    assert!(e.contains("patch light on the GPU"), "{e}");
    let t = times(&e);
    assert!(
        ["shadow maps", "direct", "gather", "shading"]
            .iter()
            .all(|p| t.contains(&format!("{p} "))),
        "{t}"
    );
    let (cpu, e) = shot("cpu");
    assert!(e.contains("patch light on the CPU"), "{e}");
    let t = times(&e);
    assert!(
        t.contains("shadow maps ")
            && t.contains("shading ")
            && !t.contains("direct ")
            && !t.contains("gather "),
        "{t}"
    );
    let (auto, e) = shot("auto");
    // `auto` keeps the faster of the two times it prints (on llvmpipe the
    // CPU, by two orders of magnitude in the gather).
    let took = e
        .lines()
        .find(|l| l.contains("a first frame took"))
        .unwrap_or_else(|| panic!("auto says what it measured: {e}"));
    let ms = |before: &str| -> f64 {
        let head = &took[..took.find(before).unwrap()];
        head.rsplit(' ').next().unwrap().parse().unwrap()
    };
    let (gpu_ms, cpu_ms) = (ms(" ms on the GPU"), ms(" ms on the CPU"));
    let chose_cpu = e.contains("patch light on the CPU");
    assert_eq!(chose_cpu, cpu_ms < gpu_ms, "{took}");
    let (worst, mean) = difference(&cpu, &gpu);
    eprintln!("CPU patch light against the GPU's: worst {worst} / 255, mean {mean:.3}");
    // Measured: worst 1, mean 0.10 (D on the patches: rays against shadow
    // maps, 1–2 % on a few shadow-edge patches); bounds several times that.
    assert!(worst <= 8 && mean <= 0.5, "worst {worst}, mean {mean}");
    let chosen = if chose_cpu { &cpu } else { &gpu };
    assert_eq!(difference(&auto, chosen).0, 0, "auto draws what it chose");
}

#[test]
fn without_a_display_the_viewer_says_so_or_renders_headless() {
    let (obj, dir) = cornell("viewer-nodisplay");
    let obj = obj.to_str().unwrap();
    let o = radiosity(&dir, &["view", obj, "--patches", "800"], false);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no display") && err.contains("radiosity render"),
        "{err}"
    );
    // The README's main command: the same view, headless, path printed.
    let png = dir.join("out").join("cornell.png");
    let o = radiosity(
        &dir,
        &[
            "view",
            obj,
            "--patches",
            "800",
            "--width",
            "160",
            "--height",
            "120",
            "--headless-to",
            png.to_str().unwrap(),
        ],
        false,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        String::from_utf8_lossy(&o.stdout).trim(),
        png.to_str().unwrap()
    );
    assert_eq!(rgb(&png).dimensions(), (160, 120));
    // Bad options are refused before anything is opened.
    let o = radiosity(&dir, &["view", obj, "--frames", "0"], false);
    assert_eq!(o.status.code(), Some(1));
    let o = radiosity(&dir, &["view", obj, "--screenshot", "x.png"], false);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--frames"));
    for (args, says) in [
        (
            &["--keys", "KeyN,Enter"][..],
            "\"Enter\" is not one the viewer acts on",
        ),
        (&["--keys", "KeyN*0"], "the count after '*'"),
        (&["--keys", "KeyN*2", "--frames", "2"], "at least 3 frames"),
        (&["--shadow-budget", "0"], "--shadow-budget 0"),
        (&["--shadow-budget", "nan"], "--shadow-budget NaN"),
    ] {
        let o = run(&dir, &[&["view", obj], args], false);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

/// Keys pressed in the window (`--keys`, as a user presses them) edit the
/// lights: the lights F5 saves are the edits the keys name, and the
/// window's last frame is what the headless renderer draws from the saved
/// file.
#[test]
fn keys_pressed_in_the_window_edit_lights_that_are_saved_and_drawn() {
    let (obj, dir) = cornell("viewer-keys");
    let obj_s = obj.to_str().unwrap();
    let size = SMALL;
    let png = |name: &str| dir.join(name).to_str().unwrap().to_string();
    // The box as bundled, and the exposure the renderer picks for it: the
    // window's later frames keep one exposure, so both sides use this one.
    let exposure = gl_render_exposure(&dir, obj_s, Path::new(&png("base.png")), &size);
    // B: a spot at the camera looking ahead; two steps left; ten times
    // dimmer by 0.8; G: a sun shining ahead, also dimmed; F5 saves. 25
    // presses after frames 1–25, frame 26 shot.
    let saved = dir.join("saved.json");
    let o = view_with_keys(
        &dir,
        obj_s,
        26,
        "KeyB,ArrowLeft*2,Minus*10,KeyG,Minus*10,F5",
        &saved,
        &exposure,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("26 frames") && err.contains("saved the camera and lights"),
        "{err}"
    );
    let bundled = radiosity::core::scene_config::load(&obj.with_extension("json")).unwrap();
    let edited = radiosity::core::scene_config::load(&saved).unwrap();
    assert_eq!(edited.camera, bundled.camera);
    assert_eq!(edited.lights.len(), 3);
    assert_eq!(edited.lights[0], bundled.lights[0]);
    let scene = radiosity::core::scene::load(&obj).unwrap();
    let (lo, hi) = scene.bounds();
    let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f32>().sqrt();
    let step = 0.01 * diagonal;
    let cam = &bundled.camera;
    match &edited.lights[1] {
        radiosity::core::scene_config::Light::Spot {
            position,
            direction,
            intensity,
            cone_angle_deg,
            beam_angle_deg,
        } => {
            // Two steps along the camera's horizontal axis (x here).
            let moved: Vec<f32> = (0..3).map(|k| position[k] - cam.position[k]).collect();
            assert!(
                (moved[0].abs() - 2.0 * step).abs() < 1e-3 * step
                    && moved[1] == 0.0
                    && moved[2] == 0.0,
                "{moved:?}, step {step}"
            );
            assert_eq!(*direction, [0.0, 0.0, 1.0]);
            assert_eq!((*cone_angle_deg, *beam_angle_deg), (30.0, 20.0));
            // A new spot is 4e4 step² W/sr; ten presses of − take 0.8 each
            // (f32 products: within 20 roundings).
            let want = 4e4 * step * step * 0.8f32.powi(10);
            for c in intensity {
                assert!(
                    (c / want - 1.0).abs() < 20.0 * f32::EPSILON,
                    "{c} against {want}"
                );
            }
        }
        l => panic!("B adds a spot, got {l:?}"),
    }
    match &edited.lights[2] {
        radiosity::core::scene_config::Light::Directional {
            direction,
            irradiance,
        } => {
            assert_eq!(*direction, [0.0, 0.0, 1.0]);
            let want = radiosity::viewer::controls::SUN_IRRADIANCE * 0.8f32.powi(10);
            for c in irradiance {
                assert!(
                    (c / want - 1.0).abs() < 20.0 * f32::EPSILON,
                    "{c} against {want}"
                );
            }
        }
        l => panic!("G adds a sun, got {l:?}"),
    }
    // The saved lights drawn headless at the same exposure: the window's
    // last frame, up to two GL contexts' rounding (as the first test).
    let shot = window_is_the_saved_file(&dir, obj_s, &saved, &exposure);
    let base = rgb(&dir.join("base.png"));
    // And the added spot shows: the picture is brighter than the box's own.
    let mean = |i: &image::RgbImage| i.pixels().map(|p| p[1] as f64).sum::<f64>() / 19200.0;
    assert!(
        mean(&shot) > 1.1 * mean(&base),
        "{} against {}",
        mean(&shot),
        mean(&base)
    );
}

/// A light whose shadow views do not fit `--shadow-budget` is taken back
/// with the sizes on stderr, and the session goes on: the next light that
/// fits is kept. With 512² maps a view is 1 MiB: the box's 60° spot takes
/// 6 views, a point 6 more (12 MiB, over 8), a 30° spot 1 (7 MiB). And a
/// session that ends early (Esc) without its screenshot exits with an
/// error.
#[test]
fn a_light_beyond_the_shadow_budget_is_taken_back_and_the_session_goes_on() {
    let (obj, dir) = cornell("viewer-budget");
    let obj_s = obj.to_str().unwrap();
    let size = ["--width", "160", "--height", "120", "--patches", "800"];
    let maps = ["--shadow-resolution", "512", "--shadow-budget", "8"];
    for mode in ["gpu", "cpu"] {
        let saved = dir.join(format!("saved-{mode}.json"));
        let o = run(
            &dir,
            &[
                &[
                    "view",
                    obj_s,
                    "--frames",
                    "4",
                    "--patch-light",
                    mode,
                    "--keys",
                    "KeyN,KeyB,F5",
                    "--save-to",
                    saved.to_str().unwrap(),
                ][..],
                &size[..],
                &maps[..],
            ],
            true,
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{mode}: {err}");
        assert!(
            err.contains(
                "the shadow maps: 12 views of 512² depth texels (points and wide spots take 6 views, other lights 1) would take 12.00 MiB, over the budget of 8.00 MiB: the last change is undone"
            ) && err.contains("4 frames"),
            "{mode}: {err}"
        );
        let lights = radiosity::core::scene_config::load(&saved).unwrap().lights;
        assert_eq!(lights.len(), 2, "{mode}: {lights:?}");
        assert!(
            matches!(lights[1], radiosity::core::scene_config::Light::Spot { .. }),
            "{mode}: {lights:?}"
        );
    }
    // Esc among the keys closes the window before the frames asked for:
    // the screenshot they were to end with is not there, and the exit
    // status says so.
    let shot = dir.join("never.png");
    let o = run(
        &dir,
        &[
            &[
                "view",
                obj_s,
                "--frames",
                "3",
                "--keys",
                "Escape",
                "--screenshot",
                shot.to_str().unwrap(),
            ][..],
            &size[..],
        ],
        true,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("the window closed after 1 of 3 frames") && !shot.exists(),
        "{err}"
    );
    // Headless, the same budget is an error naming it.
    let o = run(
        &dir,
        &[
            &[
                "render",
                obj_s,
                "--backend",
                "gl",
                "-o",
                "x.png",
                "--shadow-budget",
                "4",
            ][..],
            &size[..],
            &maps[..2],
        ],
        false,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("6.00 MiB, over the budget of 4.00 MiB"),
        "{err}"
    );
}

/// The sky keys (issue 43): Y cycles from the file's none to the sun and
/// sky, R raises its sun twice and O turns it three times; F5 saves the
/// sky, with the sun where the keys put it (45° + 10° up, 30° + 15°
/// round), and the window's last frame is what the headless renderer
/// draws from the saved file, the sky's sun and its light through the box's
/// open side included.
#[test]
fn sky_keys_cycle_skies_and_move_the_sun_and_the_window_draws_it() {
    let (obj, dir) = cornell("viewer-sky");
    let obj_s = obj.to_str().unwrap();
    let size = SMALL;
    let png = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let saved = dir.join("saved.json");
    let o = view_with_keys(&dir, obj_s, 8, "KeyY,KeyR*2,KeyO*3,F5", &saved, "1");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let edited = radiosity::core::scene_config::load(&saved).unwrap();
    match edited.sky {
        Some(radiosity::core::sky::Sky::Sunsky { sun_direction, .. }) => {
            let (e, a) = (55f32.to_radians(), 45f32.to_radians());
            let want = [e.cos() * a.sin(), e.sin(), -e.cos() * a.cos()];
            for k in 0..3 {
                assert!(
                    (sun_direction[k] - want[k]).abs() < 1e-5,
                    "{sun_direction:?}"
                );
            }
        }
        s => panic!("Y shows the sun and sky, saved {s:?}"),
    }
    let shot = window_is_the_saved_file(&dir, obj_s, &saved, "1");
    // And the sky shows: the box without it, at the same exposure, is far
    // darker.
    let o = run(
        &dir,
        &[
            &["render", obj_s, "--backend", "gl", "--exposure", "1"][..],
            &["-o", &png("base.png")][..],
            &size[..],
        ],
        false,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mean = |i: &image::RgbImage| i.pixels().map(|p| p[1] as f64).sum::<f64>() / 19200.0;
    let base = rgb(&dir.join("base.png"));
    assert!(
        mean(&shot) > 1.5 * mean(&base),
        "{} against {}",
        mean(&shot),
        mean(&base)
    );
}

/// A moving object in the window: T selects the sphere the
/// camera-and-lights file places, three presses of ← move it three steps
/// along the camera's horizontal axis, two of J turn it 30°, V shows the
/// probe view and V again hides it, F5 saves; the saved file places the
/// sphere there, and the window's last frame is what `render --backend gl`
/// draws from it (the sphere lit by the probes, with its shadow).
#[test]
fn keys_move_a_moving_object_that_is_saved_and_drawn() {
    let (obj, dir) = cornell("viewer-objects");
    let obj_s = obj.to_str().unwrap();
    // A small closed box as the object: its mesh beside the JSON file.
    let mut mesh = String::new();
    for q in common::block([-1.0; 3], [1.0; 3], [0.8; 3]) {
        for c in q.corners {
            mesh += &format!("v {} {} {}\n", c[0], c[1], c[2]);
        }
    }
    for k in 0..6 {
        let b = 4 * k + 1;
        mesh += &format!("f {} {} {} {}\n", b, b + 1, b + 2, b + 3);
    }
    std::fs::write(dir.join("cube.obj"), mesh).unwrap();
    let json = obj.with_extension("json");
    let mut config = radiosity::core::scene_config::load(&json).unwrap();
    config.objects = vec![radiosity::core::objects::Placement {
        mesh: "cube.obj".into(),
        position: [300.0, 150.0, 250.0],
        scale: 60.0,
        rotation_deg: [0.0; 3],
        resolved: None,
    }];
    config.save(&json).unwrap();
    let exposure = gl_render_exposure(&dir, obj_s, &dir.join("base.png"), &SMALL);
    let saved = dir.join("saved.json");
    let o = view_with_keys(
        &dir,
        obj_s,
        10,
        "KeyT,ArrowLeft*3,KeyJ*2,KeyV,KeyV,F5",
        &saved,
        &exposure,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("object 1/1 cube.obj"), "{err}");
    let edited = radiosity::core::scene_config::load(&saved).unwrap();
    assert_eq!(edited.objects.len(), 1);
    let scene = radiosity::core::scene::load(&obj).unwrap();
    let (lo, hi) = scene.bounds();
    let step = 0.01 * (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f32>().sqrt();
    let p = &edited.objects[0];
    let moved: Vec<f32> = (0..3)
        .map(|k| p.position[k] - [300.0, 150.0, 250.0][k])
        .collect();
    assert!(
        (moved[0].abs() - 3.0 * step).abs() < 1e-3 * step && moved[1] == 0.0 && moved[2] == 0.0,
        "{moved:?}, step {step}"
    );
    assert_eq!(p.rotation_deg, [0.0, 30.0, 0.0]);
    assert_eq!(p.mesh, "cube.obj");
    let shot = window_is_the_saved_file(&dir, obj_s, &saved, &exposure);
    // The cube is in the picture: the frame differs from the box without it.
    let bare = dir.join("bare.json");
    let mut none = edited.clone();
    none.objects.clear();
    none.save(&bare).unwrap();
    let out = dir.join("bare.png");
    let o = run(
        &dir,
        &[
            &["render", obj_s, "--backend", "gl", "--exposure", &exposure][..],
            &["--camera-lights", bare.to_str().unwrap()][..],
            &["-o", out.to_str().unwrap()][..],
            &SMALL[..],
        ],
        false,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let changed = shot
        .pixels()
        .zip(rgb(&out).pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 200, "{changed} pixels show the cube");
}

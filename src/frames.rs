//! The commands that light a bake and draw it: `render` (one image,
//! headless, on the CPU or GL) and `view` (the window), with what they
//! share: finding or making the bake, loading the camera and lights,
//! drawing headless, writing the PNG.

use crate::cli::{with_flag, DeviceArgs, RenderJob, ViewJob};
use crate::outputs::{self, ImageFormat, Inputs};
use anyhow::{bail, Context as _};
use radiosity::bake::voxelize::Resolution;
use radiosity::bake::{BakeConfig, ComputeChoice};
use radiosity::bakefile;
use radiosity::bakefile::container::write_atomic;
use radiosity::core::compute::DeviceSelection;
use radiosity::core::scene;
use radiosity::core::scene_config::SceneConfig;
use std::path::{Path, PathBuf};

/// Whether `input` is a bake file (named `.rad`, or one by its contents)
/// rather than a scene to bake.
fn is_bake_input(input: &Path) -> bool {
    input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("rad"))
        || bakefile::is_bake_file(input)
}

/// The files `render` and `view` read before loading anything: the bake
/// or the scene `input` (a scene's OBJ, MTL libraries and images), the
/// scene given with `--scene`, and the camera-and-lights file given or
/// beside the scene. (A bake's own scene is added once the bake names it.)
fn inputs_of(input: &Path, scene: Option<&Path>, camera_lights: Option<&Path>) -> Inputs {
    let mut inputs = scene_inputs_of(input, scene);
    for s in [Some(input), scene].into_iter().flatten() {
        if !is_bake_input(s) {
            inputs.file(&s.with_extension("json"), "the camera and lights");
        }
    }
    if let Some(c) = camera_lights {
        inputs.file(c, "the camera and lights");
    }
    inputs
}

/// [`inputs_of`] without the camera-and-lights files: what the viewer's
/// `--save-to` must not be (it may be the camera and lights, which its
/// saves update).
fn scene_inputs_of(input: &Path, scene: Option<&Path>) -> Inputs {
    let mut inputs = Inputs::new();
    if is_bake_input(input) {
        inputs.file(input, "the bake");
    } else {
        inputs.scene(input);
    }
    if let Some(s) = scene {
        inputs.scene(s);
    }
    inputs
}

/// The bake file for `input`: itself, or a bake of the scene (cached).
pub(crate) fn bake_for(
    input: &Path,
    patches: usize,
    device: &DeviceArgs,
) -> anyhow::Result<PathBuf> {
    if is_bake_input(input) {
        return Ok(input.to_path_buf());
    }
    let mut config = BakeConfig::new(input.to_path_buf(), Resolution::Patches(patches));
    config.compute = ComputeChoice::OpenCl(DeviceSelection::from_flag_or_env(device.device)?);
    config.validate().map_err(with_flag)?;
    let (path, _) =
        radiosity::bake::cache::bake_or_reuse(&config, &mut |l| eprintln!("[bake] {l}"))
            .with_context(|| format!("baking {}", input.display()))?;
    Ok(path)
}

/// The camera/lights file: given, or the scene's `NAME.json`, or, where the
/// scene has none, a default made for the scene
/// ([`radiosity::core::default_view`], said on stderr). `scene` is the
/// loaded scene at `scene_path` where the caller has it (else it is loaded
/// when needed).
pub(crate) fn camera_lights(
    given: Option<PathBuf>,
    scene_path: &Path,
    scene: Option<&scene::Scene>,
) -> anyhow::Result<SceneConfig> {
    let beside = scene_path.with_extension("json");
    if given.is_none() && !beside.exists() {
        return default_camera_lights(&beside, scene_path, scene);
    }
    read_camera_lights(given.unwrap_or(beside))
}

/// The camera/lights file that [`camera_lights`] would read for `input`
/// (a .rad or a scene), read *before* a bake: the one given, or the
/// scene's `NAME.json` where the scene's path is known without the bake
/// (`input` is a scene, or `scene` was given). A mistake in it then stops
/// the command at once instead of after a bake of minutes. `None`: the
/// file is chosen after the bake (a .rad names its scene) or made.
fn camera_lights_before_bake(
    given: Option<&Path>,
    input: &Path,
    scene: Option<&Path>,
) -> anyhow::Result<Option<SceneConfig>> {
    if let Some(path) = given {
        return read_camera_lights(path.to_path_buf()).map(Some);
    }
    let scene_path = match scene {
        Some(s) => s,
        None if !is_bake_input(input) => input,
        None => return Ok(None),
    };
    let beside = scene_path.with_extension("json");
    if !beside.exists() {
        return Ok(None);
    }
    read_camera_lights(beside).map(Some)
}

/// Reads and validates the camera/lights file at `path`.
fn read_camera_lights(path: PathBuf) -> anyhow::Result<SceneConfig> {
    radiosity::core::scene_config::load(&path).with_context(|| {
        format!(
            "reading the camera and lights {} (give another with --camera-lights)",
            path.display()
        )
    })
}

/// A camera and lights made for the scene at `scene_path`, which has no
/// `beside` file (said on stderr).
fn default_camera_lights(
    beside: &Path,
    scene_path: &Path,
    scene: Option<&scene::Scene>,
) -> anyhow::Result<SceneConfig> {
    let loaded;
    let scene = match scene {
        Some(s) => s,
        None => {
            loaded = scene::load(scene_path).with_context(|| {
                format!(
                    "loading the scene {} to choose a camera and lights",
                    scene_path.display()
                )
            })?;
            &loaded
        }
    };
    let config = radiosity::core::default_view::config_for(scene);
    eprintln!(
        "no camera-and-lights file {} (give one with --camera-lights): {}",
        beside.display(),
        config.description
    );
    Ok(config)
}

/// `radiosity render`.
pub(crate) fn render(job: RenderJob) -> anyhow::Result<()> {
    use radiosity::runtime::{Runtime, RuntimeOptions};
    let RenderJob {
        args,
        view,
        budget,
        format,
    } = job;
    // The outputs, before any work: none of them an input, places that
    // take them.
    let mut inputs = inputs_of(
        &args.input,
        args.scene.as_deref(),
        args.camera_lights.as_deref(),
    );
    let mut outs = vec![(args.output.as_path(), "-o")];
    if let Some(hdr) = &args.hdr {
        outs.push((hdr.as_path(), "--hdr"));
    }
    for &(out, flag) in &outs {
        inputs.check(out, flag)?;
        outputs::writable(out, flag)?;
    }
    let (baked, scene, _, config) = load_bake(
        &args.input,
        args.patches,
        &args.device,
        args.scene.clone(),
        args.camera_lights.clone(),
    )?;
    let options = RuntimeOptions {
        samples: args.samples,
        cull: args.cull,
        ..RuntimeOptions::default()
    };
    // The scene the bake names, known now.
    inputs.scene(&scene.source);
    for &(out, flag) in &outs {
        inputs.check(out, flag)?;
    }
    check_camera(&config, &scene)?;
    let mut rt = Runtime::new(baked, scene, options);
    let (img, summary) = draw_headless(
        &mut rt,
        &config,
        view,
        (args.width, args.height),
        &args.backend,
        args.shadow_resolution,
        budget,
        args.probes,
    )?;
    finite_image(&img, &config)?;
    let exposure = write_image(&args.output, format, &img, args.exposure)?;
    if let Some(hdr) = &args.hdr {
        outputs::make_parent(hdr)?;
        radiosity::runtime::tonemap::write_pfm(hdr, img.width, img.height, &img.radiance)
            .with_context(|| format!("writing {}", hdr.display()))?;
    }
    eprintln!("{summary}; exposure {}", exact(exposure));
    println!("{}", args.output.display());
    Ok(())
}

/// The bake of `input` (a .rad, or a scene baked first or taken from the
/// cache), its scene, checked to be the one it was baked from, the scene's
/// path and the camera and lights ([`camera_lights`] of `camera_lights`;
/// read before a bake where its path is known then, so that a mistake in
/// it does not wait for the bake).
pub(crate) fn load_bake(
    input: &Path,
    patches: usize,
    device: &DeviceArgs,
    scene_given: Option<PathBuf>,
    camera_lights_given: Option<PathBuf>,
) -> anyhow::Result<(
    radiosity::bakefile::baked::Baked,
    radiosity::core::scene::Scene,
    PathBuf,
    SceneConfig,
)> {
    let early = camera_lights_before_bake(
        camera_lights_given.as_deref(),
        input,
        scene_given.as_deref(),
    )?;
    let rad = bake_for(input, patches, device)?;
    let (baked, scene, scene_path) =
        radiosity::runtime::open::load_checked(&rad, scene_given.as_deref()).map_err(|e| {
            let hint = matches!(e, radiosity::runtime::open::OpenError::Scene { .. });
            let hint = if hint {
                " (--scene names the scene where it moved)"
            } else {
                ""
            };
            anyhow::Error::new(e).context(format!("opening {}{hint}", rad.display()))
        })?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let config = match early {
        Some(c) => c,
        None => camera_lights(camera_lights_given, &scene_path, Some(&scene))?,
    };
    Ok((baked, scene, scene_path, config))
}

/// Lights `rt` with `config` and draws `view` headless: on GL through EGL
/// (`backend` "gl", or "auto" when a context can be made on a GPU, not a
/// software rasterizer) or on the CPU.
/// Returns the image and a one-line summary of what was done.
#[allow(clippy::too_many_arguments)]
pub(crate) fn draw_headless(
    rt: &mut radiosity::runtime::Runtime,
    config: &SceneConfig,
    view: radiosity::runtime::render::View,
    (width, height): (usize, usize),
    backend: &str,
    shadow_resolution: usize,
    shadow_budget: Option<u64>,
    probe_view: bool,
) -> anyhow::Result<(radiosity::runtime::render::Image, String)> {
    use radiosity::runtime::render::render;
    use radiosity::runtime::texture::Albedo;
    // The sky lights the patches (D_sky, bounced into H); a bake made
    // without sky visibility says so and is drawn without it.
    if let Err(e) = rt.set_sky(config.sky.clone()) {
        eprintln!("warning: {e}");
    }
    // GL: a headless context, or (auto) the CPU when none can be made.
    let context = match backend {
        "gl" => Some(radiosity::gl::context::Headless::new().context(
            "--backend gl needs an OpenGL 4.5 context through EGL (scripts/setup installs Mesa)",
        )?),
        "auto" => match radiosity::gl::context::Headless::new() {
            // Software GL computes and rasterises on these same cores, more
            // slowly than the CPU renderer (llvmpipe, Cornell box at 3,940
            // patches: 276 ms a frame and 640 × 480 image against 2 + 46 ms).
            Ok(c) if radiosity::gl::context::is_software(&c.renderer()) => {
                eprintln!(
                    "OpenGL is software ({}): rendering on the CPU, which is faster here",
                    c.renderer()
                );
                None
            }
            Ok(c) => Some(c),
            Err(e) => {
                eprintln!("no OpenGL context ({e}): rendering on the CPU");
                None
            }
        },
        _ => None,
    };
    let out = match &context {
        Some(ctx) => {
            let gl = &ctx.gl;
            let mut r = radiosity::gl::renderer::GlRenderer::new(
                gl,
                rt,
                radiosity::gl::renderer::GlOptions {
                    shadow_resolution,
                    samples: rt.options.samples,
                    shadow_budget,
                    // Textures filtered as the CPU renderer filters them,
                    // so that both back ends draw the same image.
                    mipmaps: false,
                    ..Default::default()
                },
            )
            .context("preparing the GL renderer")?;
            // The run time's sky (none where the bake has no sky
            // visibility: said above).
            let _ = r.set_sky(gl, rt, rt.sky());
            if !config.objects.is_empty() {
                let verts = radiosity::core::objects::place_all(&config.objects)
                    .context("loading the camera-and-lights file's objects")?;
                r.set_objects(gl, &verts);
            }
            if probe_view {
                if rt.baked.probes.is_empty() {
                    anyhow::bail!(
                        "--probes: the bake has no irradiance probes (baked with --probe-spacing 0, \
                         or before probes existed): bake again"
                    );
                }
                r.set_probe_view(gl, true);
            }
            let start = std::time::Instant::now();
            let fs = r.frame(gl, &config.frame_lights(), &config.emission)?;
            let img = r.render(gl, &config.camera, view, (width, height), &config.emission)?;
            let wall = start.elapsed().as_secs_f64();
            let times = r.pass_times(gl, true);
            let passes: Vec<String> = radiosity::gl::renderer::PASSES
                .iter()
                .zip(times)
                .map(|(name, t)| match t {
                    Some(ms) => format!("{name} {ms:.2} ms"),
                    None => format!("{name} (no timer)"),
                })
                .collect();
            let s = format!(
                "gl ({}, {}): {} patches, {} light(s), {} shadow views; GPU {}; frame and image {}x{} in {wall:.3} s with read-back",
                ctx.device,
                ctx.renderer(),
                rt.n(),
                fs.lights,
                fs.views,
                passes.join(", "),
                width,
                height
            );
            r.delete(gl);
            (img, s)
        }
        None => {
            if probe_view {
                anyhow::bail!(
                    "--probes draws on the GL back end only: add --backend gl (software GL works)"
                );
            }
            if !config.objects.is_empty() {
                eprintln!(
                    "warning: the {} moving object(s) of the camera-and-lights file are drawn by \
                     the GL back end only (--backend gl); the CPU image leaves them out",
                    config.objects.len()
                );
            }
            let albedo = Albedo::new(&rt.scene);
            // The CPU image draws no moving object and no probe view: its
            // frame updates no probe.
            rt.set_probe_demand(Some(Vec::new()));
            let fs = rt.frame(&config.frame_lights(), &config.emission);
            let (img, rs) = render(rt, config, view, width, height, &albedo);
            let culled = if rt.options.cull > 0.0 {
                format!(
                    ", {} culled at --cull {}, dropping at most {:.4} % of the gathers' L1 mass",
                    fs.gather.culled_groups,
                    rt.options.cull,
                    100.0 * fs.gather.culled_mass / fs.gather.mass.max(f64::MIN_POSITIVE)
                )
            } else {
                String::new()
            };
            let s = format!(
                "cpu: {} patches, direct {:.3} s, near field {:.3} s, gather {:.3} s ({} bytes read, {:.1} % of column groups active{culled}); image {}×{} in {:.3} s ({} back-facing pixels, {} through a nearest piece, {} unmapped)",
                rt.n(),
                fs.seconds_direct,
                fs.seconds_near_field,
                fs.seconds_gather,
                fs.gather.bytes_read,
                100.0 * fs.active_groups as f64 / fs.total_groups.max(1) as f64,
                img.width,
                img.height,
                rs.seconds,
                rs.back_faces,
                rs.nearest_piece,
                rs.unmapped
            );
            (img, s)
        }
    };
    Ok(out)
}

/// The camera against the scene it looks at
/// ([`SceneConfig::check_in_scene`]).
fn check_camera(config: &SceneConfig, scene: &scene::Scene) -> anyhow::Result<()> {
    let (lo, hi) = scene.bounds();
    config
        .check_in_scene(lo, hi)
        .map_err(anyhow::Error::new)
        .context("the camera and lights (give others with --camera-lights)")
}

/// An image with a pixel that is not finite is an error naming the cause,
/// never a file: lights strong or close enough for their light on some
/// surface to overflow f32 (light powers are capped where they are read,
/// `MAX_LIGHT_POWER`, but a light a hair from a surface still overflows).
fn finite_image(
    img: &radiosity::runtime::render::Image,
    config: &SceneConfig,
) -> anyhow::Result<()> {
    let bad = img
        .radiance
        .iter()
        .filter(|p| p.iter().any(|v| !v.is_finite()))
        .count();
    if bad == 0 {
        return Ok(());
    }
    let strongest = config
        .lights
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let p = match l {
                radiosity::core::scene_config::Light::Directional { irradiance, .. } => irradiance,
                radiosity::core::scene_config::Light::Point { intensity, .. }
                | radiosity::core::scene_config::Light::Spot { intensity, .. } => intensity,
            };
            (k, p.iter().fold(0.0f32, |a, &b| a.max(b)))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let mut which = match strongest {
        Some((k, p)) => format!("the strongest light is lights[{k}], {p:e}"),
        None => "no light".to_string(),
    };
    if let Some((name, scale)) = config
        .emission
        .iter()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .filter(|(_, &s)| s > 1.0)
    {
        which += &format!("; the largest emission scale is {scale:e}, of material {name}");
    }
    bail!(
        "{bad} of {} pixels are infinite or NaN: the light on some surface overflows f32 \
         ({which}); scale the lights or the emission down (or move lights off the surfaces): \
         an --exposure shows the same image. Nothing was written",
        img.radiance.len()
    )
}

/// Writes `img` as an 8-bit sRGB image in `format` (PNG or JPEG, chosen
/// by the name: [`ImageFormat::of`]) with `exposure` (automatic when
/// `None`), through a temporary file renamed into place; returns the
/// exposure used.
pub(crate) fn write_image(
    path: &Path,
    format: ImageFormat,
    img: &radiosity::runtime::render::Image,
    exposure: Option<f32>,
) -> anyhow::Result<f32> {
    outputs::make_parent(path)?;
    let (pixels, exposure) = img.to_srgb8(exposure);
    let rgb = image::RgbImage::from_raw(img.width as u32, img.height as u32, pixels)
        .context("image size")?;
    let mut bytes = Vec::new();
    rgb.write_to(&mut std::io::Cursor::new(&mut bytes), format.image_format())?;
    write_atomic(path, &bytes, None).with_context(|| format!("writing {}", path.display()))?;
    Ok(exposure)
}

/// `x` in the shortest decimal that reads back as the same f32 (with an
/// exponent outside [10⁻⁴, 10⁶)): a printed exposure given back to
/// `--exposure` reproduces the image exactly, where four decimals printed
/// 0.0000 for the exposure of a light of 10³⁰ W/sr.
fn exact(x: f32) -> String {
    if x == 0.0 || (1e-4..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// `radiosity view`.
pub(crate) fn view(job: ViewJob) -> anyhow::Result<()> {
    use radiosity::runtime::{Runtime, RuntimeOptions};
    use radiosity::viewer::{self, ViewerConfig};
    let ViewJob {
        args,
        patch_light,
        budget,
        keys,
        headless_format,
    } = job;
    // The outputs, before any work (as `render`'s).
    let mut inputs = inputs_of(
        &args.input,
        args.scene.as_deref(),
        args.camera_lights.as_deref(),
    );
    let mut outs: Vec<(&Path, &str)> = Vec::new();
    if let Some(p) = &args.screenshot {
        outs.push((p, "--screenshot"));
    }
    if let Some(p) = &args.headless_to {
        outs.push((p, "--headless-to"));
    }
    for &(out, flag) in &outs {
        inputs.check(out, flag)?;
        outputs::writable(out, flag)?;
    }
    // The window saves its screenshot where it is told: its folder now.
    if let Some(p) = &args.screenshot {
        outputs::make_parent(p)?;
    }
    // --save-to may be the camera-and-lights file (the viewer's saves
    // update it), never the scene or the bake.
    let mut scene_inputs = scene_inputs_of(&args.input, args.scene.as_deref());
    if let Some(p) = &args.save_to {
        scene_inputs.check(p, "--save-to")?;
    }
    let (baked, scene, scene_path, config) = load_bake(
        &args.input,
        args.patches,
        &args.device,
        args.scene.clone(),
        args.camera_lights.clone(),
    )?;
    // The scene the bake names, known now.
    inputs.scene(&scene_path);
    scene_inputs.scene(&scene_path);
    check_camera(&config, &scene)?;
    for &(out, flag) in &outs {
        inputs.check(out, flag)?;
    }
    let config_path = args
        .camera_lights
        .clone()
        .unwrap_or_else(|| scene_path.with_extension("json"));
    scene_inputs.check(args.save_to.as_ref().unwrap_or(&config_path), "--save-to")?;
    let title = format!(
        "radiosity: {}",
        scene_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    );
    let rt = Runtime::new(
        baked,
        scene,
        RuntimeOptions {
            samples: args.samples,
            cull: args.cull,
            ..RuntimeOptions::default()
        },
    );
    if !viewer::has_display() {
        if let Some(png) = &args.headless_to {
            let mut rt = rt;
            eprintln!(
                "no display (DISPLAY is not set): rendering the starting view headless instead"
            );
            let (w, h) = (args.width as usize, args.height as usize);
            let (img, summary) = draw_headless(
                &mut rt,
                &config,
                radiosity::runtime::render::View::Final,
                (w, h),
                "auto",
                args.shadow_resolution,
                budget,
                false,
            )?;
            finite_image(&img, &config)?;
            let format = headless_format.expect("checked with --headless-to");
            let exposure = write_image(png, format, &img, args.exposure)?;
            eprintln!("{summary}; exposure {}", exact(exposure));
            println!("{}", png.display());
            return Ok(());
        }
    }
    let report = viewer::run(
        rt,
        ViewerConfig {
            config,
            save_to: args.save_to.clone().unwrap_or(config_path),
            width: args.width,
            height: args.height,
            frames: args.frames,
            screenshot: args.screenshot.clone(),
            gl: radiosity::gl::renderer::GlOptions {
                shadow_resolution: args.shadow_resolution,
                samples: args.samples,
                shadow_budget: budget,
                ..Default::default()
            },
            exposure: args.exposure,
            title,
            patch_light,
            keys,
        },
    )
    .map_err(|e| match e {
        viewer::ViewerError::NoDisplay(why) => anyhow::anyhow!(
            "no display to open a window on ({why}); `radiosity render --backend gl` (or `view --headless-to FILE.png`) draws the same view headless to a PNG"
        ),
        e => anyhow::Error::new(e).context("the viewer"),
    })?;
    let passes: Vec<String> = radiosity::gl::renderer::PASSES
        .iter()
        .zip(report.pass_ms)
        .filter_map(|(n, t)| t.map(|ms| format!("{n} {ms:.2} ms")))
        .collect();
    eprintln!(
        "{} frames in {:.2} s; patch light on the {}; last GPU times: {}",
        report.frames,
        report.seconds,
        match report.patch_light {
            Some(viewer::PatchLight::Cpu) => "CPU",
            _ => "GPU",
        },
        passes.join(", ")
    );
    for p in &report.screenshots {
        println!("{}", p.display());
    }
    // A window closed (or Esc pressed) before the frames asked for: the
    // screenshot they were to end with does not exist, which a script
    // must not take for success.
    if let (Some(n), Some(shot)) = (args.frames, &args.screenshot) {
        if !report.screenshots.contains(shot) {
            bail!(
                "the window closed after {} of {n} frames: {} was not written",
                report.frames,
                shot.display()
            );
        }
    }
    Ok(())
}

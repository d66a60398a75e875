//! `radiosity bench sweep`: run time against error in one command (issue
//! 14). For each scene and patch count, a baseline bake (`T_∞`, the codec
//! chosen within the default error bound, the default reordering) and one
//! bake per variation of one setting at a time (bounces, a fixed codec, a
//! reordering): one factor at a time, so each row says what that setting
//! costs or buys. Per point:
//!
//! - the bake's time per stage, its peak resident memory (the process's
//!   high-water mark, reset before each bake through
//!   `/proc/self/clear_refs`), bytes per matrix entry and the file's size;
//! - the CPU frame with nothing reused (direct light, gather), the gather
//!   over every column and over the lit ones; the GL frame pass by pass
//!   when a context can be made;
//! - the relative RMS error of the patches' `H` against the exact f64
//!   product of the same `F` with the same bounces (isolates the bounces'
//!   truncation and the codec), with the scene's own lights;
//! - classic radiosity in the same run: `k` dense f32 products with `F`
//!   (the same `k`; for `∞`, 3 bounces and Jacobi passes to the gather's
//!   error), its time and error, and the gather's speed-up.
//!
//! Output: `sweep.json` (every point), `sweep.md` (the tables) and two
//! log–log Pareto plots as SVG (`pareto_time.svg`: frame time against
//! error; `pareto_bytes.svg`: bytes per entry against error), written by
//! hand (no plotting crate: an SVG of circles, lines and text needs none).
//!
//! **Checks.** Every value must be finite, and every baseline point's
//! error at most [`SweepOptions::max_h_error`] (the bake chooses its codec
//! within 2 % over 64 random lights; with a scene's own lights it is
//! within 5 %): otherwise the sweep fails after writing its report.

use super::frame::{
    best, classic, exact_infinite, exact_series, in_matrix_order, rel_rms, time_frame,
};
use super::images::{ReferenceOptions, SceneImages};
use crate::bake::reorder::ReorderMethod;
use crate::bake::transfer::Bounces;
use crate::bake::voxelize::Resolution;
use crate::bake::{self, BakeConfig, CodecChoice, ComputeChoice};
use crate::bakefile::baked::Baked;
use crate::bakefile::codec::CodecKind;
use crate::core::compute::DeviceSelection;
use crate::core::scene;
use crate::core::scene_config::SceneConfig;
use crate::mitsuba::ImageError;
use crate::runtime::{Runtime, RuntimeOptions};
use anyhow::Context;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A scene of the sweep and its camera/lights file.
#[derive(Clone, Debug)]
pub struct SweepScene {
    pub obj: PathBuf,
    pub camera_lights: PathBuf,
}

/// What the sweep covers.
#[derive(Clone, Debug)]
pub struct SweepOptions {
    pub scenes: Vec<SweepScene>,
    pub patches: Vec<usize>,
    /// Bounce counts tried besides the baseline's `∞`.
    pub bounces: Vec<u32>,
    /// Fixed codecs tried besides the baseline's choice.
    pub codecs: Vec<CodecKind>,
    /// Reorderings tried besides the baseline's.
    pub reorders: Vec<ReorderMethod>,
    pub repeat: usize,
    pub gl: bool,
    pub selection: DeviceSelection,
    /// Where the report and the bakes go.
    pub out: PathBuf,
    /// The bound on a baseline point's error (module doc).
    pub max_h_error: f64,
    /// Image errors against Mitsuba 3 (`None`: not measured).
    pub references: Option<ReferenceOptions>,
    /// The bound on a baseline point's indirect image error against
    /// Mitsuba 3 (noise removed).
    pub max_image_error: f64,
}

impl SweepOptions {
    /// The CI sweep: the Cornell box at 256 and 600 patches; 1 and 3
    /// bounces, BC1 without its exact sparse part (the thesis's plain
    /// BC1), no reordering.
    pub fn quick(cornell: SweepScene, out: PathBuf, selection: DeviceSelection) -> SweepOptions {
        SweepOptions {
            scenes: vec![cornell],
            patches: vec![256, 600],
            bounces: vec![1, 3],
            codecs: vec![CodecKind::parse("bc1:top=0").expect("a valid codec setting")],
            reorders: vec![ReorderMethod::None],
            repeat: 2,
            gl: true,
            selection,
            references: Some(ReferenceOptions {
                dir: out.join("reference"),
                width: 160,
                height: 120,
                spp: 512,
            }),
            out,
            max_h_error: 0.05,
            max_image_error: 0.15,
        }
    }
}

/// One point of the sweep.
#[derive(Clone, Debug, Serialize)]
pub struct SweepPoint {
    pub scene: String,
    pub patches_requested: usize,
    pub patches: usize,
    /// "baseline", or the setting varied: "bounces", "codec", "reorder".
    pub varied: String,
    pub bounces: String,
    pub codec: String,
    pub reorder: String,
    pub bake_seconds: f64,
    pub bake_stages: BTreeMap<String, f64>,
    pub peak_rss_bytes: Option<u64>,
    pub bytes_per_entry: f64,
    pub matrix_bytes: u64,
    pub file_bytes: u64,
    pub cpu_frame_ms: f64,
    pub cpu_direct_ms: f64,
    pub cpu_gather_all_ms: f64,
    pub cpu_gather_lit_ms: f64,
    pub active_column_fraction: f64,
    /// GL pass times (shadow maps, direct, gather, shading) and the whole
    /// frame to `glFinish`, when GL ran.
    pub gl_pass_ms: Option<[Option<f64>; 4]>,
    pub gl_frame_ms: Option<f64>,
    pub gl_device: Option<String>,
    pub h_error: f64,
    pub classic_bounces: usize,
    pub classic_ms: f64,
    pub classic_error: f64,
    /// Classic `∞` only: Jacobi passes to reach the gather's error.
    pub classic_inf_passes: Option<usize>,
    pub classic_inf_ms: Option<f64>,
    pub speedup_vs_classic: f64,
    /// The final and indirect views against Mitsuba 3's `∞`-bounce images
    /// (for a `k`-bounce point this includes the bounces it leaves out).
    pub image_final: Option<ImageError>,
    pub image_indirect: Option<ImageError>,
    /// Samples per pixel of the reference.
    pub reference_spp: Option<u32>,
    pub all_finite: bool,
}

/// The process's peak resident memory, bytes (`VmHWM`).
fn peak_rss() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Resets the peak to the current resident memory (Linux ≥ 4.0).
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// One bake and its measurements.
fn point(
    s: &SweepScene,
    config: &SceneConfig,
    patches: usize,
    varied: &str,
    cfg: BakeConfig,
    options: &SweepOptions,
    images: Option<&mut SceneImages>,
) -> anyhow::Result<SweepPoint> {
    reset_peak_rss();
    let start = Instant::now();
    let output = bake::run(&cfg, &mut |_| {}).context("baking")?;
    let bake_seconds = start.elapsed().as_secs_f64();
    let peak = peak_rss();
    let file_bytes = cfg
        .output
        .as_ref()
        .and_then(|p| std::fs::metadata(p).ok())
        .map_or(0, |m| m.len());
    let report = &output.report;
    let name = super::images::scene_label(&s.obj, &s.camera_lights);
    let baked = Baked::from_file(&output.file, &name)?;
    let scene = scene::load(&s.obj)?;
    let n = baked.patches.len();
    let order = output.permutation.order.clone();
    let ff = &output.form_factors;
    anyhow::ensure!(
        ff.n == n,
        "the form factors hold {} patches, the bake {n}",
        ff.n
    );
    // F in matrix order (the run time's order).
    let f = in_matrix_order(&ff.f, n, &order);
    let albedo: Vec<[f32; 3]> = baked.patches.iter().map(|p| p.albedo).collect();
    let bounces = cfg.transfer.bounces;
    let matrix_bytes = baked.matrix.bytes_total() as u64;
    let bytes_per_entry = baked.matrix.bytes_per_entry();
    let codec = baked.matrix.kind.name();
    let mut rt = Runtime::new(
        baked,
        scene,
        RuntimeOptions {
            cache: false,
            ..RuntimeOptions::default()
        },
    );
    rt.set_sky(config.sky.clone())
        .context("the camera-and-lights file has a sky")?;
    let ft = time_frame(&mut rt, config, options.repeat);
    let (fs, t_frame, b0, h) = (ft.stats, ft.frame, ft.b0, ft.h);
    let (all, lit) = (ft.all, ft.lit);
    let (t_all, t_lit) = (ft.gather_all.1, ft.gather_lit.1);
    let exact = match bounces {
        Bounces::K(k) => exact_series(&f, n, &albedo, &b0, Some(k as usize)),
        Bounces::Infinite => exact_infinite(&f, n, &albedo, &b0),
    };
    let h_error = rel_rms(&h, &exact);
    let classic_k = match bounces {
        Bounces::K(k) => k as usize,
        Bounces::Infinite => 3,
    };
    let (hc, t_classic) = best(options.repeat, || classic(&f, n, &albedo, &b0, classic_k));
    let classic_error = rel_rms(&hc, &exact);
    let (classic_inf_passes, classic_inf_ms) = if bounces == Bounces::Infinite {
        let mut k = 3;
        let mut hk = hc.clone();
        while rel_rms(&hk, &exact) > h_error && k < 10_000 {
            k += 1;
            hk = classic(&f, n, &albedo, &b0, k);
        }
        let (_, t) = best(options.repeat, || classic(&f, n, &albedo, &b0, k));
        (Some(k), Some(1e3 * t))
    } else {
        (None, None)
    };
    let all_finite = b0.iter().chain(&h).flatten().all(|v| v.is_finite())
        && exact.iter().flatten().all(|v| v.is_finite());
    let (image_final, image_indirect, reference_spp) = match images {
        Some(im) => {
            let png = options
                .out
                .join("images")
                .join(format!("{name}_{n}_{varied}.png"));
            let png = (varied == "baseline").then_some(png.as_path());
            let (f, i) = super::images::errors(im, &rt, config, png)?;
            (Some(f), Some(i), Some(im.reference.spp))
        }
        None => (None, None, None),
    };
    let all_finite = all_finite
        && [image_final, image_indirect]
            .iter()
            .flatten()
            .all(|e| e.rel_rms.is_finite() && e.raw_rel_rms.is_finite());
    let (gl_pass_ms, gl_frame_ms, gl_device) = if options.gl {
        gl_frame(&rt, config, options.repeat)
    } else {
        (None, None, None)
    };
    Ok(SweepPoint {
        scene: name,
        patches_requested: patches,
        patches: n,
        varied: varied.to_string(),
        bounces: match bounces {
            Bounces::K(k) => k.to_string(),
            Bounces::Infinite => "inf".into(),
        },
        codec,
        reorder: match cfg.reorder {
            None => "default".into(),
            Some(ReorderMethod::None) => "none".into(),
            Some(ReorderMethod::Greedy { passes }) => format!("greedy:{passes}"),
            Some(ReorderMethod::SpaceFillingCurve) => "hilbert".into(),
        },
        bake_seconds,
        bake_stages: report
            .stages
            .iter()
            .map(|s| (s.stage.to_string(), s.seconds))
            .collect(),
        peak_rss_bytes: peak,
        bytes_per_entry,
        matrix_bytes,
        file_bytes,
        cpu_frame_ms: 1e3 * t_frame,
        cpu_direct_ms: 1e3 * fs.seconds_direct,
        cpu_gather_all_ms: 1e3 * t_all,
        cpu_gather_lit_ms: 1e3 * t_lit,
        active_column_fraction: lit.active_groups as f64 / all.active_groups.max(1) as f64,
        gl_pass_ms,
        gl_frame_ms,
        gl_device,
        h_error,
        classic_bounces: classic_k,
        classic_ms: 1e3 * t_classic,
        classic_error,
        classic_inf_passes,
        classic_inf_ms,
        // Against the gather over the lit columns: what a frame runs.
        speedup_vs_classic: t_classic / t_lit.max(1e-12),
        image_final,
        image_indirect,
        reference_spp,
        all_finite,
    })
}

/// The GL frame with nothing reused: pass times, the whole frame to
/// `glFinish`, the device; `None` where no context can be made.
#[allow(clippy::type_complexity)]
fn gl_frame(
    rt: &Runtime,
    config: &SceneConfig,
    repeat: usize,
) -> (Option<[Option<f64>; 4]>, Option<f64>, Option<String>) {
    use crate::gl::renderer::{GlOptions, GlRenderer};
    use glow::HasContext;
    let Ok(ctx) = crate::gl::context::Headless::new() else {
        return (None, None, None);
    };
    let gl = &ctx.gl;
    let Ok(mut r) = GlRenderer::new(
        gl,
        rt,
        GlOptions {
            cache: false,
            ..GlOptions::default()
        },
    ) else {
        return (None, None, None);
    };
    if r.set_sky(gl, rt, rt.sky()).is_err() {
        return (None, None, None);
    }
    let lights = config.frame_lights();
    let (res, t) = best(repeat, || -> Result<(), crate::gl::GlError> {
        r.frame(gl, &lights, &config.emission)?;
        r.draw(
            gl,
            &config.camera,
            crate::runtime::render::View::Final,
            (640, 480),
            &config.emission,
        )?;
        // SAFETY: waits for the GPU on the current context.
        unsafe { gl.finish() };
        Ok(())
    });
    let out = if res.is_ok() {
        (
            Some(r.pass_times(gl, true)),
            Some(1e3 * t),
            Some(ctx.renderer()),
        )
    } else {
        (None, None, None)
    };
    r.delete(gl);
    out
}

/// Runs the sweep; writes `sweep.json`, `sweep.md` and the plots under
/// `options.out`; fails (after writing) when a check fails (module doc).
pub fn run(
    options: &SweepOptions,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<Vec<SweepPoint>> {
    // The bakes are written (their size is measured) and removed.
    let bakes = super::report_dirs(&options.out, "sweep")?;
    let mut points = Vec::new();
    for s in &options.scenes {
        let config = crate::core::scene_config::load(&s.camera_lights)?;
        let mut images = match &options.references {
            Some(r) => Some(super::images::reference(
                &s.obj,
                &s.camera_lights,
                r,
                progress,
            )?),
            None => None,
        };
        for &patches in &options.patches {
            let mut variants: Vec<(String, BakeConfig)> = Vec::new();
            let base = || {
                let mut c = BakeConfig::new(s.obj.clone(), Resolution::Patches(patches));
                c.compute = ComputeChoice::OpenCl(options.selection);
                c
            };
            variants.push(("baseline".into(), base()));
            for &k in &options.bounces {
                let mut c = base();
                c.transfer.bounces = Bounces::K(k);
                variants.push(("bounces".into(), c));
            }
            for &codec in &options.codecs {
                let mut c = base();
                c.codec = CodecChoice::Fixed(codec);
                variants.push(("codec".into(), c));
            }
            for &r in &options.reorders {
                let mut c = base();
                c.reorder = Some(r);
                variants.push(("reorder".into(), c));
            }
            for (k, (varied, mut cfg)) in variants.into_iter().enumerate() {
                let stem = super::images::scene_label(&s.obj, &s.camera_lights);
                cfg.output = Some(bakes.join(format!("{stem}-{patches}-{k}.rad")));
                progress(&format!("{stem}, {patches} patches, {varied} ({})", k + 1));
                let p = point(s, &config, patches, &varied, cfg, options, images.as_mut())
                    .with_context(|| {
                        format!("{} at {patches} patches, {varied}", s.obj.display())
                    })?;
                progress(&format!(
                    "  n {}, {} bounces, {}, {:.3} B/entry: H error {:.3} %, frame {:.2} ms, gather {:.2} ms, classic {} bounces {:.2} ms ({:.1}×)",
                    p.patches,
                    p.bounces,
                    p.codec,
                    p.bytes_per_entry,
                    100.0 * p.h_error,
                    p.cpu_frame_ms,
                    p.cpu_gather_lit_ms,
                    p.classic_bounces,
                    p.classic_ms,
                    p.speedup_vs_classic
                ));
                if let (Some(f), Some(i)) = (p.image_final, p.image_indirect) {
                    progress(&format!(
                        "  vs Mitsuba 3: final {:.2} %, indirect {:.2} % (bias {:+.1} %; reference noise {:.2} % / {:.2} %)",
                        100.0 * f.rel_rms,
                        100.0 * i.rel_rms,
                        100.0 * i.bias,
                        100.0 * f.noise,
                        100.0 * i.noise
                    ));
                }
                points.push(p);
            }
        }
    }
    let _ = std::fs::remove_dir(&bakes);
    let json = serde_json::to_string_pretty(&points)?;
    std::fs::write(options.out.join("sweep.json"), json)?;
    std::fs::write(options.out.join("sweep.md"), markdown(&points, options))?;
    std::fs::write(
        options.out.join("pareto_time.svg"),
        super::svg_plot::scatter(
            "frame time against error of H",
            "relative RMS error of H vs the exact f64 solution",
            "time per frame (ms)",
            &pareto_series(&points, |p| Some(p.h_error), |p| p.cpu_frame_ms, true),
        ),
    )?;
    if points.iter().any(|p| p.image_indirect.is_some()) {
        std::fs::write(
            options.out.join("pareto_image.svg"),
            super::svg_plot::scatter(
                "frame time against image error (indirect view vs Mitsuba 3)",
                "relative RMS error of the indirect image vs Mitsuba 3 (∞ bounces)",
                "time per frame (ms)",
                &pareto_series(
                    &points,
                    |p| p.image_indirect.map(|e| e.rel_rms.max(1e-4)),
                    |p| p.cpu_frame_ms,
                    false,
                ),
            ),
        )?;
    }
    std::fs::write(
        options.out.join("pareto_bytes.svg"),
        super::svg_plot::scatter(
            "matrix size against error of H",
            "relative RMS error of H vs the exact f64 solution",
            "bytes per matrix entry",
            &pareto_series(&points, |p| Some(p.h_error), |p| p.bytes_per_entry, false),
        ),
    )?;
    let mut failures = Vec::new();
    for p in &points {
        if !p.all_finite {
            failures.push(format!(
                "{} {} {}: a non-finite value",
                p.scene, p.patches, p.varied
            ));
        }
        if let (true, Some(e)) = (p.varied == "baseline", p.image_indirect) {
            if !(e.rel_rms <= options.max_image_error) {
                failures.push(format!(
                    "{} at {} patches, baseline: indirect image error {:.2} % against Mitsuba 3 above the bound {:.1} %",
                    p.scene,
                    p.patches,
                    100.0 * e.rel_rms,
                    100.0 * options.max_image_error
                ));
            }
        }
        if p.varied == "baseline" && !(p.h_error <= options.max_h_error) {
            failures.push(format!(
                "{} at {} patches, baseline: H error {:.3} % above the bound {:.1} %",
                p.scene,
                p.patches,
                100.0 * p.h_error,
                100.0 * options.max_h_error
            ));
        }
    }
    anyhow::ensure!(
        failures.is_empty(),
        "the sweep's checks failed (report in {}):\n{}",
        options.out.display(),
        failures.join("\n")
    );
    Ok(points)
}

/// Series for a Pareto plot: the compressed gather's points per varied
/// setting, and (for time) classic radiosity's.
fn pareto_series(
    points: &[SweepPoint],
    x: impl Fn(&SweepPoint) -> Option<f64>,
    y: impl Fn(&SweepPoint) -> f64,
    classic_too: bool,
) -> Vec<super::svg_plot::Series> {
    let mut out = Vec::new();
    for (varied, colour) in [
        ("baseline", "#1f77b4"),
        ("bounces", "#2ca02c"),
        ("codec", "#ff7f0e"),
        ("reorder", "#9467bd"),
    ] {
        let pts: Vec<(f64, f64, String)> = points
            .iter()
            .filter(|p| p.varied == varied)
            .filter_map(|p| {
                Some((
                    x(p)?,
                    y(p),
                    format!("{} {} {}", p.scene, p.patches, label(p)),
                ))
            })
            .collect();
        if !pts.is_empty() {
            out.push(super::svg_plot::Series {
                name: format!("compressed gather: {varied}"),
                colour: colour.into(),
                points: pts,
            });
        }
    }
    if classic_too {
        let pts = points
            .iter()
            .map(|p| {
                (
                    p.classic_error.max(1e-9),
                    p.classic_ms,
                    format!("{} {} classic {}", p.scene, p.patches, p.classic_bounces),
                )
            })
            .collect();
        out.push(super::svg_plot::Series {
            name: "classic radiosity (same bounces; ∞ points: 3)".into(),
            colour: "#d62728".into(),
            points: pts,
        });
    }
    out
}

fn label(p: &SweepPoint) -> String {
    match p.varied.as_str() {
        "bounces" => format!("k={}", p.bounces),
        "codec" => p.codec.clone(),
        "reorder" => p.reorder.clone(),
        _ => "base".into(),
    }
}

/// The Markdown report.
fn markdown(points: &[SweepPoint], options: &SweepOptions) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Benchmark sweep\n\nMachine: {} ({} threads). Command: `radiosity bench sweep` ({} scenes, patches {:?}, repeat {}). Errors: relative RMS of the patches' H against the exact f64 product of the same F and bounces, with each scene's own lights. Times are the fastest of the repeats, in ms. Classic: dense f32 products with F, the same bounces (∞ rows: 3, and Jacobi passes to the gather's error).\n",
        cpu_name(),
        rayon::current_num_threads(),
        options.scenes.len(),
        options.patches,
        options.repeat
    );
    let _ = writeln!(
        s,
        "| scene | n | varied | bounces | codec | reorder | bake s | peak RSS MB | B/entry | file KB | H error | CPU frame | direct | gather all / lit | classic (k): ms, error | speed-up | classic ∞: passes, ms | GL frame (shadow, direct, gather, shading) | image vs Mitsuba: final, indirect (bias) |"
    );
    let _ = writeln!(
        s,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for p in points {
        let gl = match (&p.gl_pass_ms, p.gl_frame_ms) {
            (Some(t), Some(f)) => {
                let m = |v: Option<f64>| v.map_or("—".into(), |x| format!("{x:.1}"));
                format!(
                    "{f:.1} ({}, {}, {}, {})",
                    m(t[0]),
                    m(t[1]),
                    m(t[2]),
                    m(t[3])
                )
            }
            _ => "not run".into(),
        };
        let image = match (p.image_final, p.image_indirect) {
            (Some(f), Some(i)) => format!(
                "{:.2} %, {:.2} % ({:+.1} %)",
                100.0 * f.rel_rms,
                100.0 * i.rel_rms,
                100.0 * i.bias
            ),
            _ => "—".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {:.1} | {} | {:.3} | {} | {:.3} % | {:.2} | {:.2} | {:.2} / {:.2} | ({}) {:.2}, {:.2} % | {:.1}× | {} | {} | {} |",
            p.scene,
            p.patches,
            p.varied,
            p.bounces,
            p.codec,
            p.reorder,
            p.bake_seconds,
            p.peak_rss_bytes.map_or("—".into(), |b| format!("{:.0}", b as f64 / 1e6)),
            p.bytes_per_entry,
            p.file_bytes / 1024,
            100.0 * p.h_error,
            p.cpu_frame_ms,
            p.cpu_direct_ms,
            p.cpu_gather_all_ms,
            p.cpu_gather_lit_ms,
            p.classic_bounces,
            p.classic_ms,
            100.0 * p.classic_error,
            p.speedup_vs_classic,
            match (p.classic_inf_passes, p.classic_inf_ms) {
                (Some(k), Some(t)) => format!("{k}, {t:.2}"),
                _ => "—".into(),
            },
            gl,
            image
        );
    }
    let _ = writeln!(
        s,
        "\n![frame time against error](pareto_time.svg)\n\n![bytes per entry against error](pareto_bytes.svg)\n"
    );
    if let Some(r) = &options.references {
        let _ = writeln!(
            s,
            "Images: the final and indirect views of each scene's camera against Mitsuba 3 (scalar_rgb, ∞ bounces, path tracer; `scripts/mitsuba-reference`, {} × {}), relative RMS over pixels and channels with the reference's own noise removed (two independent halves; `src/mitsuba/reference.rs`); bias = relative mean difference (negative: too dark). A k-bounce point is compared with the ∞ reference, so its error includes the bounces it leaves out.\n",
            r.width, r.height
        );
        for (scene, noise, spp) in reference_noise(points) {
            let _ = writeln!(s, "- {scene}: reference noise per pixel (relative RMS of the mean) final {:.2} %, indirect {:.2} % at {spp} samples per pixel", 100.0 * noise.0, 100.0 * noise.1);
        }
        let _ = writeln!(s, "\n![frame time against image error](pareto_image.svg)\n");
    }
    s
}

/// Each scene's reference noise (final, indirect), once per scene.
fn reference_noise(points: &[SweepPoint]) -> Vec<(String, (f64, f64), u32)> {
    let mut out: Vec<(String, (f64, f64), u32)> = Vec::new();
    for p in points {
        if let (Some(f), Some(i)) = (p.image_final, p.image_indirect) {
            if !out.iter().any(|(s, _, _)| s == &p.scene) {
                out.push((
                    p.scene.clone(),
                    (f.noise, i.noise),
                    p.reference_spp.unwrap_or(0),
                ));
            }
        }
    }
    out
}

/// The CPU's model name.
pub fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|v| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into())
}

/// `path` if it exists.
pub fn existing(path: &Path) -> Option<PathBuf> {
    path.exists().then(|| path.to_path_buf())
}

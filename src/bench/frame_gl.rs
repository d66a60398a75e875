//! `bench frame`'s GPU half, on one headless GL context (EGL: a GPU where
//! there is one, else Mesa's llvmpipe, whose figures are CPU figures too):
//!
//! - **The memory roof**: a buffer copy (`crates/gl/glsl/copy.comp`) of up to 256 MiB
//!   each way, far above any GPU's caches, timed with GPU timestamps.
//! - **The gather** (`crates/gl/src/gather.rs`) over every column and over the
//!   scene's lit columns, GPU time of its three passes (no upload or read
//!   back): bytes of compressed matrix read per second, as a fraction of
//!   the copy's; and its largest difference from the CPU gather of the
//!   same `B0` against the bound of f32 summation order (2 γ_(n+1), every
//!   term being ≥ 0).
//! - **The frame** (`crates/gl/src/renderer.rs`): each pass's GPU time and the
//!   wall time to `glFinish`, at the benchmark's resolution.
//! - **Classic radiosity on the GPU** (`crates/gl/src/classic.rs`): k dense f32
//!   passes over the same `F` as the CPU's classic rows, and the Jacobi
//!   passes that reach the gather's error, against the exact `T_∞ B0`.

use super::{best, rel_rms};
use crate::core::scene_config::SceneConfig;
use crate::gl::classic::GlClassic;
use crate::gl::context::Headless;
use crate::gl::copy::GlCopy;
use crate::gl::gather::GlGather;
use crate::gl::gpu_seconds;
use crate::gl::renderer::{GlOptions, GlRenderer};
use crate::runtime::gather::ActiveColumns;
use crate::runtime::render::{render, View};
use crate::runtime::texture::Albedo;
use crate::runtime::Runtime;
use glow::HasContext;
use std::fmt::Write as _;

/// Bytes each way of the copy that measures the memory roof: far above a
/// GPU's last-level cache (50 MiB on an H200), within what every GL allows
/// one storage block (at least 128 MiB on llvmpipe; less where it says so).
const COPY_BYTES: i64 = 256 << 20;

/// The GL gather's GPU times (seconds), for the classic rows' speed-ups.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GlGatherTimes {
    pub all: f64,
    pub lit: f64,
}

/// The copy's bandwidth and the gather's rows, or why they did not run.
#[allow(clippy::too_many_arguments)]
pub(crate) fn gather_table(
    out: &mut String,
    ctx: &Headless,
    rt: &Runtime,
    b0: [&[f32]; 3],
    all: &ActiveColumns,
    lit: &ActiveColumns,
    h_cpu: &[Vec<f32>; 3],
    repeat: usize,
) -> Result<Option<GlGatherTimes>, std::fmt::Error> {
    let gl = &ctx.gl;
    // SAFETY: a query on the current context.
    let max_block = unsafe { gl.get_parameter_i64(glow::MAX_SHADER_STORAGE_BLOCK_SIZE) };
    let copy = match GlCopy::new(gl, COPY_BYTES.min(max_block).max(1 << 20) as usize) {
        Ok(c) => c,
        Err(e) => {
            writeln!(out, "\nGL gather not run: the copy kernel failed: {e}")?;
            return Ok(None);
        }
    };
    let roof = copy.bandwidth(gl, repeat.max(3));
    let moved = copy.bytes_moved();
    copy.delete(gl);
    let roof = match roof {
        Ok(r) => r,
        Err(e) => {
            writeln!(out, "\nGL gather not run: timing the copy failed: {e}")?;
            return Ok(None);
        }
    };
    let g = match GlGather::new(gl, &rt.baked.matrix) {
        Ok(g) => g,
        Err(e) => {
            writeln!(out, "\nGL gather not run: {e}")?;
            return Ok(None);
        }
    };
    let n = rt.n();
    writeln!(
        out,
        "\nGL gather on {} ({}): {} bytes of compressed matrix on the GPU; memory roof: a copy kernel moves {:.2} GB/s ({} MiB read and written, GPU timestamps, best of {})\n",
        ctx.renderer(),
        ctx.device,
        g.bytes,
        roof / 1e9,
        moved >> 20,
        repeat.max(3)
    )?;
    writeln!(
        out,
        "| GL gather (three passes, GPU time) | time | compressed matrix read | of the copy's bandwidth | largest relative difference from the CPU gather |"
    )?;
    writeln!(out, "|---|---|---|---|---|")?;
    // Every term is ≥ 0 (B0 ≥ 0, decoded entries ≥ 0): GL and CPU are each
    // within γ_(n+1) of the exact sum relatively, so within 2 γ of each
    // other (crates/gl/src/gather.rs).
    let u = f64::from(f32::EPSILON) / 2.0;
    let m = (n + 1) as f64;
    let bound = 2.0 * m * u / (1.0 - m * u);
    let mut times = [0.0f64; 2];
    for (k, (what, active)) in [("every column", all), ("lit columns", lit)]
        .into_iter()
        .enumerate()
    {
        g.set_input(gl, b0, active);
        let t = match gpu_seconds(gl, repeat, || g.run(gl)) {
            Ok(t) => t,
            Err(e) => {
                writeln!(out, "| {what} | — | failed: {e} | | |")?;
                g.delete(gl);
                return Ok(None);
            }
        };
        times[k] = t;
        let worst = match g.read_h(gl) {
            Ok(h) => (0..3)
                .flat_map(|c| h[c].iter().zip(&h_cpu[c]))
                .map(|(&x, &y)| match (x == y, y == 0.0) {
                    (true, _) => 0.0,
                    // Where the CPU's is 0 and the GPU's is not, the whole
                    // value differs.
                    (false, true) => 1.0,
                    (false, false) => f64::from((x - y) / y).abs(),
                })
                .fold(0.0, f64::max),
            Err(e) => {
                writeln!(out, "| {what} | — | failed: {e} | | |")?;
                g.delete(gl);
                return Ok(None);
            }
        };
        let bytes = g.bytes_read(active);
        let groups = 100.0 * active.active_groups as f64 / all.active_groups.max(1) as f64;
        writeln!(
            out,
            "| {what} ({groups:.1} % of column groups) | {:.4} ms | {bytes} bytes: {:.2} GB/s | {:.1} % | {:.2e} (bound 2 γ_{} = {:.2e}) |",
            1e3 * t,
            bytes as f64 / t / 1e9,
            100.0 * bytes as f64 / t / roof,
            worst,
            n + 1,
            bound
        )?;
    }
    g.delete(gl);
    Ok(Some(GlGatherTimes {
        all: times[0],
        lit: times[1],
    }))
}

/// Classic radiosity's rows on the GPU: 1, 2, 3 bounces and `k_inf`
/// Jacobi passes (the CPU rows' count reaching the gather's error) over
/// the same `F`, against the same exact `H`; with the GL gather's speed-up
/// over each.
#[allow(clippy::too_many_arguments)]
pub(crate) fn classic_rows(
    out: &mut String,
    ctx: &Headless,
    f: &[f32],
    n: usize,
    albedo: &[[f32; 3]],
    b0: &[Vec<f32>; 3],
    exact: &[Vec<f64>; 3],
    k_inf: usize,
    gather: Option<GlGatherTimes>,
    repeat: usize,
) -> std::fmt::Result {
    let gl = &ctx.gl;
    let c = match GlClassic::new(gl, f, n, albedo) {
        Ok(c) => c,
        Err(e) => return writeln!(out, "| classic on the GPU | — | not run: {e} | |"),
    };
    for k in [1, 2, 3, k_inf] {
        c.set_input(gl, b0);
        let t = gpu_seconds(gl, 1, || c.run(gl, k));
        // Timed again from the same input: H accumulates, so each timed run
        // starts from set_input (its upload is outside the GPU time).
        let t = t.and_then(|first| {
            let mut best = first;
            for _ in 1..repeat.max(1) {
                c.set_input(gl, b0);
                best = best.min(gpu_seconds(gl, 1, || c.run(gl, k))?);
            }
            Ok(best)
        });
        let h = t.and_then(|t| Ok((t, c.bounces(gl, b0, k)?)));
        let (t, h) = match h {
            Ok(v) => v,
            Err(e) => {
                c.delete(gl);
                return writeln!(out, "| classic on the GPU | — | failed: {e} | |");
            }
        };
        let label = if k == k_inf && k > 3 {
            format!("GL classic ∞ (Jacobi, {k} passes to reach the gather's error)")
        } else {
            format!("GL classic, {k} bounce{}", if k > 1 { "s" } else { "" })
        };
        let speedup = gather.map_or("—".to_string(), |g| {
            format!(
                "{:.1}× every column, {:.1}× lit columns",
                t / g.all,
                t / g.lit
            )
        });
        writeln!(
            out,
            "| {label} | {:.4} ms ({:.2} GB/s of F) | {:.3} % | GL gather {speedup} |",
            1e3 * t,
            c.bytes_per_pass() as f64 * k as f64 / t / 1e9,
            100.0 * rel_rms(&h, exact),
        )?;
    }
    c.delete(gl);
    Ok(())
}

/// The GL frame (`crates/gl/src/renderer.rs`) on a headless context: the GPU time
/// of each pass (timestamp queries) for a frame with nothing reused, with
/// and without column skipping, the wall time of a whole frame and image
/// (to `glFinish`), and an unchanged frame; or why it did not run. On
/// Mesa's llvmpipe these are CPU figures too.
pub(crate) fn frame_table(
    out: &mut String,
    ctx: &Headless,
    rt: &Runtime,
    config: &SceneConfig,
    (width, height): (usize, usize),
    repeat: usize,
    cpu_frame: f64,
) -> std::fmt::Result {
    let gl = &ctx.gl;
    let mut r = match GlRenderer::new(
        gl,
        rt,
        GlOptions {
            cache: false,
            samples: rt.options.samples,
            ..GlOptions::default()
        },
    ) {
        Ok(r) => r,
        Err(e) => return writeln!(out, "\nGL frame not run: {e}"),
    };
    let size = (width, height);
    // The run time's sky, and the file's lights with the sky's sun.
    if let Err(e) = r.set_sky(gl, rt, rt.sky()) {
        return writeln!(out, "\nGL frame not run: {e}");
    }
    let lights = config.frame_lights();
    // A frame (its patch light on GL, or `H` from the CPU run time: the
    // viewer's `--patch-light cpu`), the image drawn, to `glFinish`.
    let frame_from = |r: &mut GlRenderer, cpu_h: bool| -> Result<(), crate::gl::GlError> {
        if cpu_h {
            r.frame_with_h(gl, &lights, &config.emission, rt.h(), rt.h_points())?;
        } else {
            r.frame(gl, &lights, &config.emission)?;
        }
        r.draw(gl, &config.camera, View::Final, size, &config.emission)?;
        // SAFETY: waits for the GPU on the current context.
        unsafe { gl.finish() };
        Ok(())
    };
    let (res, t_frame) = best(repeat, || frame_from(&mut r, false));
    if let Err(e) = res {
        return writeln!(out, "\nGL frame failed: {e}");
    }
    let passes = r.pass_times(gl, true);
    // The sky's cost: the same frame without it (its sun kept: a light),
    // and what a change of sky costs (`D_sky` and the background table).
    let sky_cost = match rt.sky() {
        None => None,
        Some(sky) => {
            let _ = r.set_sky(gl, rt, None);
            let (_, without) = best(repeat, || frame_from(&mut r, false));
            let t0 = std::time::Instant::now();
            let _ = r.set_sky(gl, rt, Some(sky));
            Some((without, t0.elapsed().as_secs_f64()))
        }
    };
    r.options.skip_columns = false;
    let (_, t_all) = best(repeat, || frame_from(&mut r, false));
    let passes_all = r.pass_times(gl, true);
    r.options.skip_columns = true;
    r.options.cache = true;
    let _ = r.frame(gl, &lights, &config.emission);
    let (_, t_unchanged) = best(repeat, || {
        let _ = r.frame(gl, &lights, &config.emission);
    });
    // `H` from the CPU run time (its frame timed above), uploaded.
    r.options.cache = false;
    let (res, t_with_h) = best(repeat, || frame_from(&mut r, true));
    if let Err(e) = res {
        return writeln!(out, "\nGL frame with H from the CPU failed: {e}");
    }
    let passes_with_h = r.pass_times(gl, true);
    let ms = |t: Option<f64>| t.map_or("—".to_string(), |v| format!("{v:.3} ms"));
    writeln!(
        out,
        "\nGL frame on {} ({}), {} × {}, shadow maps {}², GPU times of the last of {} frames (timestamp queries)\n",
        ctx.renderer(),
        ctx.device,
        width,
        height,
        r.options.shadow_resolution,
        repeat
    )?;
    writeln!(
        out,
        "| pass | lit columns | every column | H from the CPU run time (`view --patch-light cpu`) |"
    )?;
    writeln!(out, "|---|---|---|---|")?;
    for (k, name) in crate::gl::renderer::PASSES.iter().enumerate() {
        // Direct light and the gather ran on the CPU: no GPU time.
        let with_h = passes_with_h[k].map_or("not run".to_string(), |v| format!("{v:.3} ms"));
        writeln!(
            out,
            "| {name} | {} | {} | {with_h} |",
            ms(passes[k]),
            ms(passes_all[k])
        )?;
    }
    writeln!(
        out,
        "| whole frame and image, wall clock to glFinish | {:.3} ms | {:.3} ms | {:.3} ms + the CPU frame {:.3} ms = {:.3} ms |",
        1e3 * t_frame,
        1e3 * t_all,
        1e3 * t_with_h,
        1e3 * cpu_frame,
        1e3 * (t_with_h + cpu_frame)
    )?;
    writeln!(
        out,
        "| unchanged frame (nothing runs) | {:.4} ms | | |",
        1e3 * t_unchanged
    )?;
    if let (Some((without, t_set)), Some(sky)) = (sky_cost, rt.sky()) {
        writeln!(
            out,
            "| the sky ({}): the frame above less the frame without it | +{:.3} ms (of {:.3} ms without) | | a change of sky (`D_sky` on the CPU, the background table): {:.2} ms |",
            sky.kind(),
            1e3 * (t_frame - without),
            1e3 * without,
            1e3 * t_set
        )?;
    }
    // The images against the CPU renderer's (the reference: one ray per
    // pixel centre, its own H), textures filtered alike.
    r.options.mipmaps = false;
    let albedo = Albedo::new(&rt.scene);
    let mut diffs = Vec::new();
    for view in [View::Final, View::Indirect] {
        let gpu = r
            .frame(gl, &lights, &config.emission)
            .and_then(|_| r.render(gl, &config.camera, view, size, &config.emission));
        match gpu {
            Ok(gpu) => {
                let (cpu, _) = render(rt, config, view, size.0, size.1, &albedo);
                let (e, coverage) = gpu.difference(&cpu);
                diffs.push(format!(
                    "{view:?} {:.2} % relative RMS (coverage differs on {:.2} % of pixels)",
                    100.0 * e,
                    100.0 * coverage
                ));
            }
            Err(e) => diffs.push(format!("{view:?} failed: {e}")),
        }
    }
    writeln!(
        out,
        "\nGL images against the CPU renderer's at {} × {} (textures bilinear on both, no mipmaps): {}",
        size.0,
        size.1,
        diffs.join("; ")
    )?;
    r.delete(gl);
    Ok(())
}

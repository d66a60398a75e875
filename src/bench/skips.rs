//! `radiosity bench skips`: what each scene does not need, and what
//! skipping it saves (issue 14, item 4). Per scene, one bake and its run
//! time:
//!
//! - **Bake** (counts from the bake's report): voxel patches removed because
//!   they see nothing, covered geometry left out of every patch, and the
//!   matrix entries that saves; the form-factor rays not cast — with the
//!   default method (rays from the real surfaces) the origins drawn on
//!   covered parts of pieces, with the pair method the pairs culled by each
//!   rule (facing away, blocked with a certificate) at the measured rays
//!   per evaluated pair — and the time that saves at the bake's measured
//!   rays per second (an estimate: the bake cannot turn these off, and
//!   what they skip is exactly zero either way); zero tiles of the dense
//!   part, neither stored nor read, and their bytes.
//! - **Run time** (measured by turning each skip off in the same run, the
//!   fastest of `repeat` runs): zero columns of `B0` (the gather over every
//!   column against the lit ones; identical results); identical channels
//!   (a grey `B0` through a grey matrix gathered once, against the same
//!   gather forced to three channels); an unchanged frame against a full
//!   one; one light of several moved (only its term recomputed) against a
//!   full frame; and the zero tiles' bytes at the gather's measured
//!   throughput (an estimate: no encoding stores them).
//!
//! Output: `skips.json` and `skips.md`.

use super::frame::{best, best_alternating};
use super::sweep::SweepScene;
use crate::bake::voxelize::Resolution;
use crate::bake::{self, BakeConfig, ComputeChoice};
use crate::bakefile::baked::Baked;
use crate::core::compute::DeviceSelection;
use crate::core::scene;
use crate::core::scene_config::{Light, SceneConfig};
use crate::runtime::gather::ActiveColumns;
use crate::runtime::{Runtime, RuntimeOptions};
use anyhow::Context;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;

/// What the skip report covers.
#[derive(Clone, Debug)]
pub struct SkipsOptions {
    pub scenes: Vec<SweepScene>,
    pub patches: usize,
    pub repeat: usize,
    pub selection: DeviceSelection,
    pub out: PathBuf,
}

/// One scene's skips (module doc).
#[derive(Clone, Debug, Default, Serialize)]
pub struct SceneSkips {
    pub scene: String,
    // Bake: patches and geometry.
    pub voxel_patches: u64,
    pub patches: u64,
    pub removed_patches: u64,
    pub covered_pieces: u64,
    pub partly_covered_pieces: u64,
    pub covered_area_share: f64,
    /// `1 − n² / n_voxel²`: matrix entries saved by the removed patches.
    pub entries_saved_fraction: f64,
    // Bake: form factors.
    /// `"rays"` (from the real surfaces) or `"pairs"` (patch pairs).
    pub form_factor_method: String,
    /// Rays method: rays that left the scene or met a back face (cast, but
    /// carrying nothing), and origins on covered parts (not cast).
    pub rays_escaped: u64,
    pub rays_back_face: u64,
    pub rays_covered: u64,
    pub pairs_total: u64,
    pub pairs_evaluated: u64,
    pub pairs_backfacing: u64,
    pub pairs_blocked: u64,
    pub pairs_evaluated_zero: u64,
    pub rays_cast: u64,
    pub form_factor_seconds: f64,
    /// Estimated (module doc).
    pub rays_saved_estimate: f64,
    pub form_factor_seconds_saved_estimate: f64,
    // Codec.
    pub grey_matrix: bool,
    pub zero_tile_fraction: f64,
    pub zero_tile_bytes: f64,
    pub matrix_bytes: u64,
    // Run time, measured.
    pub frame_full_ms: f64,
    pub gather_all_columns_ms: f64,
    pub gather_lit_columns_ms: f64,
    pub lit_column_fraction: f64,
    pub bytes_read_all: u64,
    pub bytes_read_lit: u64,
    pub gather_grey_ms: Option<f64>,
    pub gather_grey_forced_rgb_ms: Option<f64>,
    pub frame_unchanged_ms: f64,
    pub frame_one_light_moved_ms: Option<f64>,
    pub lights: usize,
    /// Estimated: the zero tiles' bytes at the gather's measured
    /// throughput over every column.
    pub zero_tiles_gather_ms_saved_estimate: f64,
}

/// Runs the report; writes `skips.json` and `skips.md` into `options.out`.
pub fn run(
    options: &SkipsOptions,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<Vec<SceneSkips>> {
    let bakes = super::report_dirs(&options.out, "skips")?;
    let mut out = Vec::new();
    for s in &options.scenes {
        let stem = s
            .obj
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        progress(&format!("{stem}: baking at {} patches", options.patches));
        let r = scene_skips(s, &stem, options, &bakes)
            .with_context(|| format!("{}", s.obj.display()))?;
        progress(&format!(
            "  {} of {} voxel patches kept; form-factor rays not cast {:.3e}; zero tiles {:.1} %; gather lit/all {:.2}/{:.2} ms; unchanged frame {:.3} ms of {:.2}",
            r.patches,
            r.voxel_patches,
            r.rays_saved_estimate,
            100.0 * r.zero_tile_fraction,
            r.gather_lit_columns_ms,
            r.gather_all_columns_ms,
            r.frame_unchanged_ms,
            r.frame_full_ms
        ));
        out.push(r);
    }
    let _ = std::fs::remove_dir_all(&bakes);
    std::fs::write(
        options.out.join("skips.json"),
        serde_json::to_string_pretty(&out)?,
    )?;
    std::fs::write(options.out.join("skips.md"), markdown(&out, options))?;
    Ok(out)
}

fn scene_skips(
    s: &SweepScene,
    stem: &str,
    options: &SkipsOptions,
    bakes: &std::path::Path,
) -> anyhow::Result<SceneSkips> {
    let config: SceneConfig = crate::core::scene_config::load(&s.camera_lights)?;
    let mut cfg = BakeConfig::new(s.obj.clone(), Resolution::Patches(options.patches));
    cfg.compute = ComputeChoice::OpenCl(options.selection);
    cfg.output = Some(bakes.join(format!("{stem}.rad")));
    let output = bake::run(&cfg, &mut |_| {}).context("baking")?;
    let rep = &output.report;
    let ff = &rep.form_factors;
    let baked = Baked::from_file(&output.file, stem)?;
    let scene = scene::load(&s.obj)?;
    let ff_seconds = ff.seconds_total;
    let rays_method = ff
        .options
        .as_ref()
        .is_some_and(|o| o.method == crate::bake::form_factor::FormFactorMethod::Rays);
    let rays_saved = if rays_method {
        ff.rays_covered as f64
    } else {
        let rays_per_pair = ff.rays_cast as f64 / ff.pairs_evaluated.max(1) as f64;
        rays_per_pair * (ff.skipped_backfacing + ff.skipped_blocked) as f64
    };
    let rays_per_second = ff.rays_per_second;
    let m = &baked.matrix;
    let stored = m.index.cols.len();
    let dense_per_tile = m.bytes_dense() as f64 / stored.max(1) as f64;
    let tiles = m.index.tiles_per_side * m.index.tiles_per_side;
    let zero_tile_bytes = dense_per_tile * (tiles - stored) as f64;
    let area = rep.scene.area.max(1e-300);
    let n_vox = ff.patches.max(1) as f64;
    let mut r = SceneSkips {
        scene: stem.to_string(),
        voxel_patches: ff.patches,
        patches: ff.kept,
        removed_patches: ff.removed_patches,
        covered_pieces: rep.voxels.covered_pieces,
        partly_covered_pieces: rep.voxels.partly_covered_pieces,
        covered_area_share: rep.voxels.covered_area / area,
        entries_saved_fraction: 1.0 - (ff.kept as f64 / n_vox).powi(2),
        form_factor_method: if rays_method { "rays" } else { "pairs" }.into(),
        rays_escaped: ff.rays_escaped,
        rays_back_face: ff.rays_back_face,
        rays_covered: ff.rays_covered,
        pairs_total: ff.pairs_total,
        pairs_evaluated: ff.pairs_evaluated,
        pairs_backfacing: ff.skipped_backfacing,
        pairs_blocked: ff.skipped_blocked,
        pairs_evaluated_zero: ff.evaluated_zero,
        rays_cast: ff.rays_cast,
        form_factor_seconds: ff_seconds,
        rays_saved_estimate: rays_saved,
        form_factor_seconds_saved_estimate: rays_saved / rays_per_second.max(1e-9),
        grey_matrix: m.channels == 1,
        zero_tile_fraction: m.zero_tile_fraction(),
        zero_tile_bytes,
        matrix_bytes: m.bytes_total() as u64,
        lights: config.lights.len(),
        ..Default::default()
    };
    // Run time: each skip turned off and on again on one runtime (the
    // cache option is read at every frame).
    let mut rt = Runtime::new(baked, scene, RuntimeOptions::default());
    let repeat = options.repeat;
    rt.options.cache = false;
    let (_, t_full) = best(repeat, || rt.frame(&config.lights, &config.emission));
    r.frame_full_ms = 1e3 * t_full;
    rt.options.cache = true;
    rt.frame(&config.lights, &config.emission);
    let (st, t_unchanged) = best(repeat, || rt.frame(&config.lights, &config.emission));
    anyhow::ensure!(
        st.unchanged,
        "a repeated frame was not recognised as unchanged"
    );
    r.frame_unchanged_ms = 1e3 * t_unchanged;
    if config.lights.len() >= 2 {
        // Move the last light back and forth by a small step: one term
        // recomputed per frame, the others reused.
        let (lo, hi) = rt.scene.bounds();
        let step = 1e-3 * (0..3).map(|k| (hi[k] - lo[k]) as f64).fold(0.0, f64::max);
        let mut moved = config.lights.clone();
        let mut flip = false;
        let (_, t) = best(repeat, || {
            flip = !flip;
            let dx = if flip { step } else { -step } as f32;
            if let Some(l) = moved.last_mut() {
                *l = shifted(l, dx);
            }
            rt.frame(&moved, &config.emission)
        });
        r.frame_one_light_moved_ms = Some(1e3 * t);
    }
    // Zero columns, on `B0` of the scene's own lights (the moved-light
    // frames above changed it).
    rt.frame(&config.lights, &config.emission);
    let b0 = rt.b0().clone();
    let refs = [&b0[0][..], &b0[1][..], &b0[2][..]];
    let tile = rt.baked.matrix.index.tile;
    let all = ActiveColumns::of(refs, tile, true);
    let lit = ActiveColumns::of(refs, tile, false);
    let mut h = rt.h().clone();
    // One untimed pass first: thread pool and caches warm for both.
    rt.gather.gather(refs, &all, &mut h);
    let mut h2 = h.clone();
    let ((sa, ta), (sl, tl)) = best_alternating(
        repeat,
        || rt.gather.gather(refs, &all, &mut h),
        || rt.gather.gather(refs, &lit, &mut h2),
    );
    r.gather_all_columns_ms = 1e3 * ta;
    r.gather_lit_columns_ms = 1e3 * tl;
    r.lit_column_fraction = lit.active_groups as f64 / all.active_groups.max(1) as f64;
    r.bytes_read_all = sa.bytes_read;
    r.bytes_read_lit = sl.bytes_read;
    r.zero_tiles_gather_ms_saved_estimate =
        1e3 * ta * zero_tile_bytes / (sa.bytes_read as f64).max(1.0);
    // Identical channels: a grey B0 (the luminance of this frame's B0 in
    // every channel) gathered once through a grey matrix, against the same
    // values with the third channel nudged by one ulp, which forces three.
    if r.grey_matrix {
        let grey: Vec<f32> = (0..b0[0].len())
            .map(|i| (b0[0][i] + b0[1][i] + b0[2][i]) / 3.0)
            .collect();
        let nudged: Vec<f32> = grey
            .iter()
            .map(|&v| {
                if v > 0.0 {
                    f32::from_bits(v.to_bits() + 1)
                } else {
                    v
                }
            })
            .collect();
        let g = [&grey[..], &grey[..], &grey[..]];
        let forced = [&grey[..], &grey[..], &nudged[..]];
        let mut h2 = h.clone();
        let ((_, t1), (_, t3)) = best_alternating(
            repeat,
            || rt.gather.gather(g, &all, &mut h),
            || rt.gather.gather(forced, &all, &mut h2),
        );
        r.gather_grey_ms = Some(1e3 * t1);
        r.gather_grey_forced_rgb_ms = Some(1e3 * t3);
    }
    Ok(r)
}

/// `l` moved by `dx` along x (a directional light turns slightly instead).
fn shifted(l: &Light, dx: f32) -> Light {
    let mut l = l.clone();
    match &mut l {
        Light::Point { position, .. } | Light::Spot { position, .. } => position[0] += dx,
        Light::Directional { direction, .. } => direction[0] += dx,
    }
    l
}

fn markdown(rows: &[SceneSkips], options: &SkipsOptions) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# What each scene does not need\n\nMachine: {} ({} threads). Command: `radiosity bench skips --patches {}` (fastest of {} runs). Bake counts come from the bake's report; \"est.\" marks savings estimated from rates measured in the same bake (the bake cannot turn those rules off: their pairs are exactly zero either way); run-time savings are measured by turning each skip off in the same run.\n",
        super::sweep::cpu_name(),
        rayon::current_num_threads(),
        options.patches,
        options.repeat
    );
    let _ = writeln!(s, "## Bake\n\n| scene | voxel patches → kept (removed: see nothing) | covered geometry (pieces, partly, area share) | matrix entries saved | form factors: method; rays cast (left the scene, met a back face) or pairs culled (backfacing, blocked) | rays not cast | form factors s; saved (est.) | zero tiles: share, bytes | grey matrix |\n|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let method = if r.form_factor_method == "rays" {
            format!(
                "rays; {:.3e} ({:.1} %, {:.2} %)",
                r.rays_cast as f64,
                100.0 * r.rays_escaped as f64 / (r.rays_cast.max(1)) as f64,
                100.0 * r.rays_back_face as f64 / (r.rays_cast.max(1)) as f64
            )
        } else {
            format!(
                "pairs; {} of {} ({}, {})",
                r.pairs_backfacing + r.pairs_blocked,
                r.pairs_total,
                r.pairs_backfacing,
                r.pairs_blocked
            )
        };
        let _ = writeln!(
            s,
            "| {} | {} → {} ({}) | {}, {}, {:.1} % | {:.1} % | {} | {:.3e} | {:.2}; {:.2} | {:.1} %, {:.0} kB | {} |",
            r.scene,
            r.voxel_patches,
            r.patches,
            r.removed_patches,
            r.covered_pieces,
            r.partly_covered_pieces,
            100.0 * r.covered_area_share,
            100.0 * r.entries_saved_fraction,
            method,
            r.rays_saved_estimate,
            r.form_factor_seconds,
            r.form_factor_seconds_saved_estimate,
            100.0 * r.zero_tile_fraction,
            r.zero_tile_bytes / 1e3,
            if r.grey_matrix { "yes (1 channel stored)" } else { "no" }
        );
    }
    let _ = writeln!(s, "\n## Run time (ms; each skip on → off)\n\n| scene | full frame | zero columns: gather lit → all (lit share; bytes read) | identical channels: grey gather → forced RGB | unchanged frame → full | one of several lights moved → full | zero tiles: gather time saved (est.) |\n|---|---|---|---|---|---|---|");
    for r in rows {
        let grey = match (r.gather_grey_ms, r.gather_grey_forced_rgb_ms) {
            (Some(a), Some(b)) => format!("{a:.2} → {b:.2} ({:.1}×)", b / a.max(1e-9)),
            _ => "— (colour matrix)".into(),
        };
        let moved = match r.frame_one_light_moved_ms {
            Some(t) => format!(
                "{t:.2} → {:.2} ({:.1}×)",
                r.frame_full_ms,
                r.frame_full_ms / t.max(1e-9)
            ),
            None => format!("— ({} light)", r.lights),
        };
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.2} → {:.2} ({:.1} %; {:.1} → {:.1} MB) | {} | {:.4} → {:.2} | {} | {:.2} |",
            r.scene,
            r.frame_full_ms,
            r.gather_lit_columns_ms,
            r.gather_all_columns_ms,
            100.0 * r.lit_column_fraction,
            r.bytes_read_lit as f64 / 1e6,
            r.bytes_read_all as f64 / 1e6,
            grey,
            r.frame_unchanged_ms,
            r.frame_full_ms,
            moved,
            r.zero_tiles_gather_ms_saved_estimate
        );
    }
    s
}

//! `radiosity bench compression`: the compression report
//! (`docs/compression.md`): every reordering × codec on each scene's
//! transfer matrix, with the errors of `T̃` and of `H = T̃ · B0` over seeded
//! random lights, bytes per entry and times.

use super::cpu_model;
use crate::bake::encode::{self, measure, CodecError};
use crate::bake::error::BakeError;
use crate::bake::reorder::{self, ReorderMethod};
use crate::bake::voxelize::Resolution;
use crate::bake::{self, BakeConfig};
use crate::bakefile::codec::{CodecKind, CodecSettingError, SparseValues, LOG_RANGE_AUTO};
use crate::core::compute::{Backend, DeviceSelection, Gpu};
use crate::core::direct;
use crate::core::patch::Patch;
use crate::core::permutation::Permutation;
use anyhow::Context as _;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the compression report ([`compression_report`]) measures, besides
/// the scenes: every reordering times every codec, over seeded random
/// lights, on one OpenCL device.
#[derive(Clone, Debug)]
pub struct CompressionOptions {
    pub methods: Vec<ReorderMethod>,
    pub kinds: Vec<CodecKind>,
    /// The number of seeded random lights ([`direct::random_lights`]); each
    /// light alone gives one `B0` sample.
    pub lights: usize,
    pub seed: u64,
    pub selection: DeviceSelection,
}

impl Default for CompressionOptions {
    /// The report's standard grid: the four reorderings and eight codec
    /// settings of issue 5, 64 lights, seed 1, the default device.
    fn default() -> Self {
        CompressionOptions {
            methods: default_compression_methods(),
            kinds: default_compression_kinds(),
            lights: 64,
            seed: 1,
            selection: DeviceSelection::Default,
        }
    }
}

impl CompressionOptions {
    /// Checks the option values that do not depend on a scene.
    pub fn validate(&self) -> Result<(), BakeError> {
        if self.methods.is_empty() {
            return Err(BakeError::Mismatch {
                stage: "compression report",
                detail: "the compression report needs at least one reordering".into(),
            });
        }
        if self.kinds.is_empty() {
            return Err(BakeError::Mismatch {
                stage: "compression report",
                detail: "the compression report needs at least one codec".into(),
            });
        }
        if self.lights == 0 {
            return Err(BakeError::Mismatch {
                stage: "compression report",
                detail: "the compression report needs at least one light".into(),
            });
        }
        Ok(self.kinds.iter().try_for_each(CodecKind::validate)?)
    }
}

/// The reorderings the report compares: the voxelizer's order, the
/// thesis's greedy chain with one and two passes, and the Hilbert order.
pub fn default_compression_methods() -> Vec<ReorderMethod> {
    vec![
        ReorderMethod::None,
        ReorderMethod::Greedy { passes: 1 },
        ReorderMethod::Greedy { passes: 2 },
        ReorderMethod::SpaceFillingCurve,
    ]
}

/// The codec settings the report compares: the thesis's, the default
/// (top 4 %, automatic log range, RGB9E5 sparse values) and the same with
/// f16 and f32 sparse values, BC1 with RGB9E5 sparse values at top 3 %,
/// 2 % and 0 %, BC4 at top 2 %, BC6H, f16 and f32.
pub fn default_compression_kinds() -> Vec<CodecKind> {
    let bc1 = |top_fraction, sparse| CodecKind::Bc1Log {
        top_fraction,
        log_range: LOG_RANGE_AUTO,
        sparse,
    };
    vec![
        CodecKind::THESIS,
        CodecKind::default(),
        bc1(0.04, SparseValues::F16),
        bc1(0.04, SparseValues::F32),
        bc1(0.03, SparseValues::Rgb9e5),
        bc1(0.02, SparseValues::Rgb9e5),
        bc1(0.0, SparseValues::Rgb9e5),
        CodecKind::Bc4Log {
            top_fraction: 0.02,
            log_range: LOG_RANGE_AUTO,
            sparse: SparseValues::Rgb9e5,
        },
        CodecKind::Bc6h,
        CodecKind::F16,
        CodecKind::F32,
    ]
}

/// The size and accuracy the compression aims at (issue 5): at most this
/// many bytes per entry in all (dense, sparse and index parts)...
pub const TARGET_BYTES_PER_ENTRY: f64 = 0.75;
/// ... with a relative RMS error of `H = T̃ · B0` of at most this.
pub const TARGET_H_ERROR: f64 = 0.02;

/// The compression report on one scene, as a Markdown section: load →
/// voxelize at `patches` target patches → form factors → `T_∞` (all on
/// OpenCL), the direct light of each seeded random light on the kept
/// patches (CPU, with shadows) as the `B0` samples, then every reordering
/// times every codec through `report_rows`, and a line naming the
/// best row under the target ([`TARGET_BYTES_PER_ENTRY`],
/// [`TARGET_H_ERROR`]). `progress` gets one line per stage.
pub fn compression(
    scene_path: &Path,
    patches: usize,
    options: &CompressionOptions,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<String> {
    options.validate()?;
    let gpu = Gpu::new(options.selection).context("opening the OpenCL device")?;
    compression_section(scene_path, patches, options, &gpu, progress)
}

/// The whole compression report (`docs/compression.md`): a preamble (how it
/// was made, `command` being the command line to regenerate it, the
/// machine, what the columns mean, the thesis's figures), then one
/// [`compression`] section per `(scene, target patches)`.
pub fn compression_report(
    scenes: &[(PathBuf, usize)],
    options: &CompressionOptions,
    command: &str,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<String> {
    options.validate()?;
    if scenes.is_empty() {
        return Err(BakeError::Mismatch {
            stage: "compression report",
            detail: "the compression report needs at least one scene".into(),
        }
        .into());
    }
    let gpu = Gpu::new(options.selection).context("opening the OpenCL device")?;
    let start = Instant::now();
    let mut sections = Vec::new();
    for (path, patches) in scenes {
        sections.push(
            compression_section(path, *patches, options, &gpu, progress)
                .with_context(|| format!("compression report on {}", path.display()))?,
        );
    }
    let mut out = compression_preamble(scenes, options, &gpu, command)?;
    writeln!(
        out,
        "The whole report took {:.0} s of wall time.\n",
        start.elapsed().as_secs_f64()
    )?;
    for s in sections {
        out.push_str(&s);
        out.push('\n');
    }
    Ok(out)
}

/// The report's preamble (see [`compression_report`]).
fn compression_preamble(
    scenes: &[(PathBuf, usize)],
    options: &CompressionOptions,
    gpu: &Gpu,
    command: &str,
) -> anyhow::Result<String> {
    let mut out = String::new();
    let info = gpu.info();
    let scene_list: Vec<String> = scenes
        .iter()
        .map(|(p, n)| format!("`{}` at {n} target patches", p.display()))
        .collect();
    writeln!(out, "# Compression of the transfer matrix: measurements\n")?;
    writeln!(
        out,
        "Generated by `scripts/compression-report`, which builds the release binary and runs\n\n\
         ```\n{command}\n```\n\n\
         Do not edit by hand: run the script again. The code is `bench::compression_report`\n\
         (src/bench/compression.rs) around its `report_rows` and `report_table`.\n"
    )?;
    writeln!(
        out,
        "**Machine.** {} hardware threads ({}; rayon uses {}); OpenCL is {} on {} ({}). \
         No GPU: every stage, the OpenCL ones included, ran on these CPU cores, and other \
         jobs shared them during the run, so times are indicative only (compare them within \
         one table).\n",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        cpu_model().unwrap_or_else(|| "CPU model unknown".into()),
        rayon::current_num_threads(),
        info.platform,
        info.name,
        info.kind,
    )?;
    writeln!(
        out,
        "**What is measured.** Scenes: {}. For each: load → voxelize (target patch count) → \
         form factors (default options: 4 × 4 samples, 4 visibility rays) → transfer matrix \
         `T_∞` (infinite bounces), all on OpenCL; n is the number of patches the form-factor \
         stage keeps. `B0` samples: {} seeded random lights (`direct::random_lights`, seed {}; \
         even indices directional, odd ones spot lights), *each light alone* one sample, its \
         direct irradiance computed on the CPU with shadow rays (`direct::DirectLight`) and \
         turned into exitance `B0 = ρ ∘ D + E`. Then for each reordering ({}) the matrix and \
         the samples are permuted (the greedy distances on OpenCL), and each codec ({}) encodes, \
         decodes and is measured against the uncompressed `T` in f64.\n",
        scene_list.join(", "),
        options.lights,
        options.seed,
        options
            .methods
            .iter()
            .map(|m| format!("`{m}`"))
            .collect::<Vec<_>>()
            .join(", "),
        options
            .kinds
            .iter()
            .map(|k| format!("`{k}`"))
            .collect::<Vec<_>>()
            .join(", "),
    )?;
    writeln!(
        out,
        "**Columns.**\n\
         - *mean abs, max abs, total abs*: the thesis's table, the absolute error \
         `|T̃_ij − T_ij|` over all 3 n² entries (three channels), its mean, maximum and sum.\n\
         - *rel. Frob. T*: `‖T̃ − T‖_F / ‖T‖_F`, channels pooled.\n\
         - *rel. RMS H*: `‖H̃ − H‖ / ‖H‖` with `H = T B0`, pooled over all samples, channels \
         and patches; *worst H*: the same for the worst single sample (light).\n\
         - *B/entry dense, sparse, index, total*: bytes of the dense texture (stored tiles \
         only), the sparse top fraction (column indices and values), the tile index, and \
         their sum, divided by n² (one entry = one patch pair, all three channels).\n\
         - *reorder s*: time of the reordering (the same for every codec of one reordering); \
         *encode s*: time of the encoder; *tiles skipped*: the share of 32 × 32 tiles of the \
         dense part that are zero in every channel and not stored.\n\
         - Codec names: `bc1-log(top=f,L=…,v)` is BC1 of log-scaled bytes with log range L \
         (`auto`: chosen from the data; the thesis fixes 25) and the top fraction f of entries \
         kept in a sparse part with values in v (f32 exact, f16, or rgb9e5: three channels \
         in one shared-exponent word); `bc4-log` the same with one BC4 image \
         per channel; `bc6h`, `f16`, `f32` plain (module doc of crates/bakefile/src/codec/mod.rs).\n"
    )?;
    writeln!(
        out,
        "**Target** (issue 5): at most {TARGET_BYTES_PER_ENTRY} bytes per entry in all with a \
         relative RMS error of H of at most {} %. Each section ends with the best row under \
         it (lowest H error), or says none reaches it.\n",
        100.0 * TARGET_H_ERROR
    )?;
    writeln!(
        out,
        "**The thesis's figures**, for comparison (its own scene and matrix, BC1 of log-scaled \
         values with L = 25 and the top 4 % exact, about 1.5 bytes per entry), mean / max / \
         total absolute error of the entries:\n\n\
         | thesis reordering | mean abs | max abs | total abs |\n\
         |---|---|---|---|\n\
         | none | 1.28e-6 | 0.4622 | 47.12 |\n\
         | greedy, one pass | 8.13e-7 | 0.4684 | 18.86 |\n\
         | greedy, two passes | 5.88e-7 | 0.1524 | 9.40 |\n\n\
         The absolute errors scale with n and with how the matrix is normalised, so only the \
         trend across reorderings is comparable with the tables below, not the values; \
         the relative errors are the measure this project reports.\n"
    )?;
    Ok(out)
}

/// One scene's section of the report (see [`compression`]).
fn compression_section(
    scene_path: &Path,
    patches: usize,
    options: &CompressionOptions,
    gpu: &Gpu,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<String> {
    if patches == 0 {
        return Err(BakeError::Mismatch {
            stage: "compression report",
            detail: "the target patch count must be at least 1".into(),
        }
        .into());
    }
    let backend = Backend::OpenCl(gpu);
    let config = BakeConfig::new(scene_path.to_path_buf(), Resolution::Patches(patches));
    let bake::TransferStages {
        scene,
        vox,
        patches: kept,
        transfer: tr,
        stages: bake_stages,
        ..
    } = bake::transfer_stages(&config, &backend, progress)?;
    let mut stages: Vec<(&str, f64)> = bake_stages.iter().map(|s| (s.stage, s.seconds)).collect();
    let mut stage = |name, t: Instant| stages.push((name, t.elapsed().as_secs_f64()));

    progress(&format!(
        "direct light of {} random lights (seed {})",
        options.lights, options.seed
    ));
    let t = Instant::now();
    let b0_samples = direct::light_samples(&scene, &kept, options.lights, options.seed);
    let dark = b0_samples
        .iter()
        .filter(|b| b.iter().all(|c| c.iter().all(|&x| x == 0.0)))
        .count();
    stage("direct light", t);

    progress(&format!(
        "{} reorderings × {} codecs",
        options.methods.len(),
        options.kinds.len()
    ));
    let t = Instant::now();
    let n = tr.n;
    let rows = report_rows(
        [tr.channel(0), tr.channel(1), tr.channel(2)],
        n,
        &kept,
        &b0_samples,
        &options.methods,
        &options.kinds,
        Backend::OpenCl(gpu),
    )?;
    stage("reorder + encode + measure", t);

    let name = scene_path.file_stem().map_or_else(
        || scene_path.display().to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    let info = gpu.info();
    let mut out = String::new();
    writeln!(out, "## {name} (`{}`)\n", scene_path.display())?;
    writeln!(
        out,
        "- n = {n} patches kept (of {} from the voxelizer at voxel size {:.4}, target {patches}); \
         {} triangles\n\
         - bounces: {}{}\n\
         - lights: {} seeded random (seed {}), {} of them light no patch\n\
         - device: {} ({}, {})\n\
         - stage times: {}\n",
        vox.patches.len(),
        vox.stats.voxel_size,
        scene.triangles.len(),
        tr.stats.bounces,
        if tr.grey { " (grey: one channel)" } else { "" },
        options.lights,
        options.seed,
        dark,
        info.name,
        info.kind,
        info.platform,
        stages
            .iter()
            .map(|(s, secs)| format!("{s} {secs:.1} s"))
            .collect::<Vec<_>>()
            .join(", "),
    )?;
    out.push_str(&report_table(&rows));
    out.push('\n');
    out.push_str(&target_line(&rows));
    out.push('\n');
    Ok(out)
}

/// The line naming the best row under the target: among the rows with at
/// most [`TARGET_BYTES_PER_ENTRY`] bytes per entry and at most
/// [`TARGET_H_ERROR`] H error, the lowest H error (ties: fewer bytes), and
/// the cheapest; else the lowest H error within the byte budget.
fn target_line(rows: &[ReportRow]) -> String {
    let describe = |r: &ReportRow| {
        format!(
            "`{}` + `{}` ({:.2} % H error, {:.3} B/entry)",
            r.reorder,
            r.codec,
            100.0 * r.error.rel_rms_h,
            r.bytes_per_entry
        )
    };
    let by_error = |a: &&ReportRow, b: &&ReportRow| {
        a.error
            .rel_rms_h
            .total_cmp(&b.error.rel_rms_h)
            .then(a.bytes_per_entry.total_cmp(&b.bytes_per_entry))
    };
    let budget: Vec<&ReportRow> = rows
        .iter()
        .filter(|r| r.bytes_per_entry <= TARGET_BYTES_PER_ENTRY)
        .collect();
    let meeting: Vec<&ReportRow> = budget
        .iter()
        .copied()
        .filter(|r| r.error.rel_rms_h <= TARGET_H_ERROR)
        .collect();
    let target = format!(
        "≤ {TARGET_BYTES_PER_ENTRY} B/entry with H error ≤ {} %",
        100.0 * TARGET_H_ERROR
    );
    match meeting.iter().copied().min_by(by_error) {
        Some(best) => {
            let cheapest = meeting
                .iter()
                .copied()
                .min_by(|a, b| {
                    a.bytes_per_entry
                        .total_cmp(&b.bytes_per_entry)
                        .then(a.error.rel_rms_h.total_cmp(&b.error.rel_rms_h))
                })
                .expect("not empty");
            format!(
                "**Target** ({target}): met by {} of {} rows; best {}; cheapest {}.\n",
                meeting.len(),
                rows.len(),
                describe(best),
                describe(cheapest)
            )
        }
        None => match budget.iter().copied().min_by(by_error) {
            Some(closest) => format!(
                "**Target** ({target}): no row reaches it; the lowest H error within the byte \
                 budget is {}.\n",
                describe(closest)
            ),
            None => format!(
                "**Target** ({target}): no row reaches it; no row is within the byte budget.\n"
            ),
        },
    }
}

/// Reads one codec of the compression report's `--codec` flag:
/// [`CodecKind::parse`]'s syntax, or `thesis` ([`CodecKind::THESIS`]) or
/// `default` ([`CodecKind::default`]).
pub fn parse_report_codec(s: &str) -> Result<CodecKind, CodecSettingError> {
    match s.trim().to_ascii_lowercase().as_str() {
        "thesis" => Ok(CodecKind::THESIS),
        "default" => Ok(CodecKind::default()),
        _ => CodecKind::parse(s),
    }
}

/// One line of the compression report.
#[derive(Clone, Debug, Serialize)]
pub struct ReportRow {
    pub reorder: String,
    pub reorder_seconds: f64,
    pub codec: String,
    pub error: CodecError,
    pub bytes_dense_per_entry: f64,
    pub bytes_sparse_per_entry: f64,
    pub bytes_index_per_entry: f64,
    pub bytes_per_entry: f64,
    pub encode_seconds: f64,
    pub tiles_skipped_fraction: f64,
    pub flushed_entries: u64,
    pub mixed_zero_blocks: u64,
    pub zeros_lost: u64,
}

/// Every reordering in `methods` times every codec in `kinds`: the
/// matrix and the B0 samples are permuted, encoded, decoded and measured
/// (the measures do not depend on the labelling).
pub fn report_rows(
    t: [&[f32]; 3],
    n: usize,
    patches: &[Patch],
    b0_samples: &[[Vec<f32>; 3]],
    methods: &[ReorderMethod],
    kinds: &[CodecKind],
    backend: Backend,
) -> Result<Vec<ReportRow>, BakeError> {
    let mut rows = Vec::new();
    let grey = crate::bakefile::codec::distinct_channels(t).len() == 1;
    for &method in methods {
        // `Backend` is not `Copy`: a fresh value per reordering.
        let b = match &backend {
            Backend::Cpu => Backend::Cpu,
            Backend::OpenCl(g) => Backend::OpenCl(g),
        };
        let (perm, rstats) = reorder::reorder_with_stats(method, t, n, patches, b)?;
        let (tp, bp) = permute_problem(&perm, t, n, b0_samples, grey);
        let tref: [&[f32]; 3] = [&tp[0], &tp[1 % tp.len()], &tp[2 % tp.len()]];
        for &kind in kinds {
            let e = encode::encode(kind, tref, n)?;
            let err = measure(tref, n, &e.decode(), &bp);
            let per = |b: usize| b as f64 / (n * n).max(1) as f64;
            rows.push(ReportRow {
                reorder: method.name(),
                reorder_seconds: rstats.seconds,
                codec: kind.name(),
                error: err,
                bytes_dense_per_entry: per(e.bytes_dense()),
                bytes_sparse_per_entry: per(e.bytes_sparse()),
                bytes_index_per_entry: per(e.bytes_index()),
                bytes_per_entry: e.bytes_per_entry(),
                encode_seconds: e.stats.seconds,
                tiles_skipped_fraction: e.stats.tiles_skipped_fraction,
                flushed_entries: e.stats.flushed_entries,
                mixed_zero_blocks: e.stats.mixed_zero_blocks,
                zeros_lost: e.stats.zeros_lost,
            });
        }
    }
    Ok(rows)
}

/// The matrix (distinct channels only when grey) and the B0 samples in the
/// order of `perm`.
fn permute_problem(
    perm: &Permutation,
    t: [&[f32]; 3],
    n: usize,
    b0_samples: &[[Vec<f32>; 3]],
    grey: bool,
) -> (Vec<Vec<f32>>, Vec<[Vec<f32>; 3]>) {
    let channels: &[&[f32]] = if grey { &t[..1] } else { &t[..] };
    let tp = channels
        .iter()
        .map(|c| perm.apply_symmetric(c, n))
        .collect();
    let bp = b0_samples
        .iter()
        .map(|b| std::array::from_fn(|c| perm.apply_vec(&b[c])))
        .collect();
    (tp, bp)
}

/// The report as a Markdown table: the thesis's entry errors (mean, max,
/// total), the relative Frobenius error of T̃, the relative RMS error of H
/// (and the worst sample), bytes per entry (dense, sparse, index, total),
/// reorder and encode times, and the skipped tiles.
pub fn report_table(rows: &[ReportRow]) -> String {
    let mut s = String::new();
    s.push_str(
        "| reorder | codec | mean abs | max abs | total abs | rel. Frob. T | rel. RMS H | worst H \
         | B/entry dense | sparse | index | total | reorder s | encode s | tiles skipped |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3} | {:.3} | \
             {:.4} | {:.3} | {:.2} | {:.2} | {:.1} % |",
            r.reorder,
            r.codec,
            r.error.mean_abs,
            r.error.max_abs,
            r.error.total_abs,
            r.error.rel_frobenius,
            r.error.rel_rms_h,
            r.error.max_rel_h,
            r.bytes_dense_per_entry,
            r.bytes_sparse_per_entry,
            r.bytes_index_per_entry,
            r.bytes_per_entry,
            r.reorder_seconds,
            r.encode_seconds,
            100.0 * r.tiles_skipped_fraction
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::encode::CodecError;
    use crate::bench::shell_command_line;

    fn row(reorder: &str, h: f64, bytes: f64) -> ReportRow {
        ReportRow {
            reorder: reorder.into(),
            reorder_seconds: 0.0,
            codec: "c".into(),
            error: CodecError {
                rel_rms_h: h,
                ..CodecError::default()
            },
            bytes_dense_per_entry: bytes,
            bytes_sparse_per_entry: 0.0,
            bytes_index_per_entry: 0.0,
            bytes_per_entry: bytes,
            encode_seconds: 0.0,
            tiles_skipped_fraction: 0.0,
            flushed_entries: 0,
            mixed_zero_blocks: 0,
            zeros_lost: 0,
        }
    }

    #[test]
    fn target_line_names_the_lowest_error_and_the_cheapest_row_meeting_the_target() {
        let rows = [
            row("a", 0.001, 1.0), // too many bytes
            row("b", 0.015, 0.70),
            row("c", 0.019, 0.50),
            row("d", 0.030, 0.40), // too much error
        ];
        let line = target_line(&rows);
        assert!(line.contains("met by 2 of 4 rows"), "{line}");
        assert!(line.contains("best `b`"), "{line}");
        assert!(line.contains("cheapest `c`"), "{line}");
    }

    #[test]
    fn target_line_says_when_no_row_meets_the_target() {
        let line = target_line(&[row("a", 0.05, 0.5), row("b", 0.01, 2.0)]);
        assert!(line.contains("no row reaches it"), "{line}");
        assert!(line.contains("`a`"), "{line}");
        let line = target_line(&[row("b", 0.01, 2.0)]);
        assert!(line.contains("no row is within the byte budget"), "{line}");
    }

    #[test]
    fn report_codecs_accept_the_aliases_and_the_codec_syntax() {
        assert_eq!(parse_report_codec("thesis").unwrap(), CodecKind::THESIS);
        assert_eq!(parse_report_codec("Default").unwrap(), CodecKind::default());
        assert_eq!(
            parse_report_codec("bc1:top=0.02,L=auto,sparse=rgb9e5").unwrap(),
            default_compression_kinds()[5]
        );
        assert!(parse_report_codec("bc7").is_err());
        // Every default setting reads back from its name.
        for k in default_compression_kinds() {
            assert_eq!(parse_report_codec(&k.name()).unwrap(), k);
        }
    }

    #[test]
    fn command_lines_quote_what_the_shell_would_interpret() {
        let args: Vec<String> = ["radiosity", "--codec", "bc1(top=0.02);f16", "it's", ""]
            .map(String::from)
            .to_vec();
        assert_eq!(
            shell_command_line(&args),
            r"radiosity --codec 'bc1(top=0.02);f16' 'it'\''s' ''"
        );
    }

    #[test]
    fn options_refuse_empty_lists_and_no_lights() {
        assert!(CompressionOptions::default().validate().is_ok());
        for o in [
            CompressionOptions {
                methods: vec![],
                ..CompressionOptions::default()
            },
            CompressionOptions {
                kinds: vec![],
                ..CompressionOptions::default()
            },
            CompressionOptions {
                lights: 0,
                ..CompressionOptions::default()
            },
        ] {
            assert!(o.validate().is_err());
        }
    }
}

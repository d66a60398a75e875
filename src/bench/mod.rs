//! Benchmarks behind `radiosity bench`: every time is printed beside its
//! error against a named reference (here: the f64 CPU reference, measured
//! in the same run), and throughput beside the machine's measured memory
//! bandwidth. Timings on a shared 2-core machine are noisy; compare the
//! ratios within one run.

use crate::bake::reorder::ReorderMethod;
use crate::bake::voxelize::{self, Resolution};
use crate::bake::{self, BakeConfig};
use crate::bakefile::codec::{self, CodecKind, ReportRow, SparseValues, LOG_RANGE_AUTO};
use crate::core::compute::Backend;
use crate::core::compute::{DeviceSelection, Gpu};
use crate::core::direct;
use crate::core::error::BakeError;
use crate::core::scene;
use anyhow::Context as _;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Host memory bandwidth in bytes/s: the best of a few copies of a 256 MiB
/// buffer (read + write counted), a STREAM-copy-like figure.
pub fn memory_bandwidth() -> f64 {
    let n = 32 << 20; // 32 Mi u64 = 256 MiB
    let src = vec![1u64; n];
    let mut dst = vec![0u64; n];
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        dst.copy_from_slice(&src);
        std::hint::black_box(&mut dst);
        best = best.min(t.elapsed().as_secs_f64());
    }
    (2 * n * 8) as f64 / best
}

fn best_of<T>(repeat: usize, mut f: impl FnMut() -> anyhow::Result<T>) -> anyhow::Result<(T, f64)> {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeat {
        let t = Instant::now();
        let v = f()?;
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    Ok((last.expect("repeat >= 1"), best))
}

/// Voxelization on OpenCL against the CPU reference at each voxel size.
/// Returns a printable table.
pub fn voxelize(
    scene_path: &Path,
    sizes: &[f64],
    repeat: usize,
    selection: DeviceSelection,
) -> anyhow::Result<String> {
    let scene = scene::load(scene_path)?;
    let gpu = Gpu::new(selection).context("opening the OpenCL device")?;
    let bandwidth = memory_bandwidth();
    let mut out = String::new();
    writeln!(
        out,
        "voxelization of {} ({} triangles) on {} ({}); CPU reference: f64, rayon on {} threads; host memory bandwidth {:.1} GB/s",
        scene_path.display(),
        scene.triangles.len(),
        gpu.info().name,
        gpu.info().platform,
        rayon::current_num_threads(),
        bandwidth * 1e-9
    )?;
    writeln!(
        out,
        "| voxel size | grid | patches | pieces | OpenCL (s) | kernels (s) | CPU ref (s) | CPU/OpenCL | patches only in OpenCL / CPU | max albedo diff | max area diff (voxel faces) | piece bytes/s vs bandwidth |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    for &size in sizes {
        let (cl, t_cl) = best_of(repeat, || {
            Ok(voxelize::voxelize_at(&scene, size, &Backend::OpenCl(&gpu))?)
        })?;
        let (cpu, t_cpu) = best_of(repeat, || {
            Ok(voxelize::voxelize_at(&scene, size, &Backend::Cpu)?)
        })?;
        let cmp = voxelize::compare(&cl, &cpu);
        let piece_bytes = cl.stats.candidate_pieces as f64 * 32.0;
        writeln!(
            out,
            "| {size} | {}x{}x{} | {} | {} | {:.3} | {:.3} | {:.3} | {:.2} | {} / {} | {:.2e} | {:.2e} | {:.2e} |",
            cl.grid.dims[0],
            cl.grid.dims[1],
            cl.grid.dims[2],
            cl.stats.patches,
            cl.stats.pieces,
            t_cl,
            cl.stats.seconds_kernels,
            t_cpu,
            t_cpu / t_cl,
            cmp.only_in_a,
            cmp.only_in_b,
            cmp.max_albedo_diff,
            cmp.max_area_diff_faces,
            piece_bytes / cl.stats.seconds_pieces.max(1e-9) / bandwidth
        )?;
    }
    Ok(out)
}

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
            return Err(BakeError::Options(
                "the compression report needs at least one reordering".into(),
            ));
        }
        if self.kinds.is_empty() {
            return Err(BakeError::Options(
                "the compression report needs at least one codec".into(),
            ));
        }
        if self.lights == 0 {
            return Err(BakeError::Options(
                "the compression report needs at least one light".into(),
            ));
        }
        self.kinds.iter().try_for_each(CodecKind::validate)
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
/// times every codec through [`codec::report_rows`], and a line naming the
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
        return Err(
            BakeError::Options("the compression report needs at least one scene".into()).into(),
        );
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

/// The machine's CPU model from `/proc/cpuinfo`, if readable.
fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    info.lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, m)| m.trim().to_string())
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
         (src/bench.rs) around `codec::report_rows` and `codec::report_table` (src/codec.rs).\n"
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
         per channel; `bc6h`, `f16`, `f32` plain (module doc of src/codec.rs).\n"
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
        return Err(BakeError::Options("the target patch count must be at least 1".into()).into());
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
    let rows = codec::report_rows(
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
    out.push_str(&codec::report_table(&rows));
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
pub fn parse_report_codec(s: &str) -> Result<CodecKind, BakeError> {
    match s.trim().to_ascii_lowercase().as_str() {
        "thesis" => Ok(CodecKind::THESIS),
        "default" => Ok(CodecKind::default()),
        _ => CodecKind::parse(s),
    }
}

/// `args` as one shell command line, each argument single-quoted where it
/// holds characters the shell would interpret, for the report's preamble.
pub fn shell_command_line(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_./:=,+-@%".contains(c));
            if plain {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bakefile::codec::CodecError;

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

//! The bake pipeline as one call: validated options in, a report (and the
//! `.rad` file) out. Stages (DESIGN.md section 1, bake steps 1–8): load →
//! voxelize → form factors → transfer → reorder → encode → mesh-to-patch
//! map → write. The compression error of the bake is measured on the way:
//! `H = T̃ · B0` against the exact `T · B0` over seeded random lights
//! ([`crate::core::direct::random_lights`], direct light with shadows on the CPU),
//! and `--max-error` uses the same lights to choose the codec.
//!
//! Everything written to the file is deterministic (no timestamps, no
//! timings): the same scene and options give the same bytes. Timings go to
//! the terminal report only.

pub mod encode;
pub mod error;
pub mod form_factor;
pub mod gemm;
pub mod mesh_map;
pub mod preview;
pub mod reorder;
pub mod transfer;
pub mod voxelize;

use crate::bake::error::BakeError;
use crate::bakefile::baked::stored_scene_path;
use crate::bakefile::codec::{CodecKind, Encoded};
use crate::bakefile::records::{
    BakeInfo, BouncesRecord, OptionsRecord, INFO_RECORD_VERSION, OPTIONS_RECORD_VERSION,
};
use crate::bakefile::{self, BakeFile, PatchRecord, SceneHash};
use crate::core::compute::Backend;
use crate::core::compute::{DeviceSelection, Gpu};
use crate::core::direct;
use crate::core::npy;
use crate::core::patch::Patch;
use crate::core::permutation::Permutation;
use crate::core::scene::{self, SceneSummary};
use anyhow::Context as _;
use form_factor::{FormFactorOptions, FormFactorStats, FormFactors};
use mesh_map::MeshMapStats;
use reorder::{ReorderMethod, ReorderStats};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;
use transfer::{Bounces, Transfer, TransferOptions, TransferStats};
use voxelize::{Resolution, VoxelStats};

/// Where the bake's OpenCL stages run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ComputeChoice {
    /// An OpenCL device (the default).
    OpenCl(DeviceSelection),
    /// The CPU reference implementation of every stage (slow, exact).
    CpuReference,
}

/// How the codec is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum CodecChoice {
    /// This setting.
    Fixed(CodecKind),
    /// The cheapest of [`codec::default_candidates`] whose relative RMS
    /// error of `H` over the error lights is at most this.
    MaxError(f64),
}

impl Default for CodecChoice {
    fn default() -> Self {
        CodecChoice::Fixed(CodecKind::default())
    }
}

/// Seed of the random lights the compression error is measured over (the
/// same as the compression report's, `docs/compression.md`).
pub const ERROR_LIGHTS_SEED: u64 = 1;

/// Default number of those lights.
pub const DEFAULT_ERROR_LIGHTS: usize = 64;

/// The validated options of one bake.
#[derive(Clone, Debug, Serialize)]
pub struct BakeConfig {
    pub scene: PathBuf,
    pub resolution: Resolution,
    pub compute: ComputeChoice,
    pub form_factor: FormFactorOptions,
    pub transfer: TransferOptions,
    /// The reordering; `None`: [`ReorderMethod::default_for`] the patch count.
    pub reorder: Option<ReorderMethod>,
    pub codec: CodecChoice,
    /// Seeded random lights the compression error is measured over (0: not
    /// measured; `--max-error` needs at least 1).
    pub error_lights: usize,
    /// The bake file to write, if any.
    #[serde(skip)]
    pub output: Option<PathBuf>,
    /// Directory for inspection files (`patches.csv`, `patches.png`,
    /// `F.npy`, `T.npy`, `T_decoded.npy`, `albedo.npy`), if asked for.
    #[serde(skip)]
    pub export: Option<PathBuf>,
}

impl BakeConfig {
    /// The default options for `scene` at `resolution`, on the default
    /// OpenCL device, writing nothing.
    pub fn new(scene: PathBuf, resolution: Resolution) -> BakeConfig {
        BakeConfig {
            scene,
            resolution,
            compute: ComputeChoice::OpenCl(DeviceSelection::default()),
            form_factor: FormFactorOptions::default(),
            transfer: TransferOptions::default(),
            reorder: None,
            codec: CodecChoice::default(),
            error_lights: DEFAULT_ERROR_LIGHTS,
            output: None,
            export: None,
        }
    }

    /// Checks option values that do not depend on the scene.
    pub fn validate(&self) -> Result<(), BakeError> {
        match self.resolution {
            Resolution::VoxelSize(s) if !(s.is_finite() && s > 0.0) => {
                return Err(BakeError::InvalidOption {
                    option: "voxel size",
                    value: s.to_string(),
                    expected: "a positive finite number".into(),
                })
            }
            Resolution::Patches(0) => {
                return Err(BakeError::InvalidOption {
                    option: "patch count",
                    value: "0".into(),
                    expected: "at least 1".into(),
                })
            }
            _ => {}
        }
        match self.codec {
            CodecChoice::Fixed(kind) => kind.validate()?,
            CodecChoice::MaxError(e) if !(e.is_finite() && e >= 0.0) => {
                return Err(BakeError::InvalidOption {
                    option: "maximum codec error",
                    value: e.to_string(),
                    expected: "a finite number ≥ 0".into(),
                })
            }
            CodecChoice::MaxError(_) if self.error_lights == 0 => {
                return Err(BakeError::InvalidOption {
                    option: "error lights",
                    value: "0".into(),
                    expected: "at least 1 when the codec is chosen by its error".into(),
                })
            }
            CodecChoice::MaxError(_) => {}
        }
        Ok(())
    }
}

/// Time and outcome of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
}

/// The compressed matrix of a bake: the setting, its sizes and its error.
#[derive(Clone, Debug, Serialize)]
pub struct CodecSummary {
    /// The setting ([`CodecKind::name`]).
    pub codec: String,
    /// How it was chosen: `"fixed"` or `"max-error E"`.
    pub chosen_by: String,
    /// Bytes of the dense tiles, the sparse part and the tile index.
    pub bytes_dense: u64,
    pub bytes_sparse: u64,
    pub bytes_index: u64,
    /// All bytes per matrix entry (three channels together), and the dense
    /// and sparse parts' shares.
    pub bytes_per_entry: f64,
    pub bytes_per_entry_dense: f64,
    pub bytes_per_entry_sparse: f64,
    /// Uncompressed f32 size of the three channels over the total.
    pub compression_ratio: f64,
    /// Tiles of the dense part that are zero in every channel, not stored.
    pub zero_tile_fraction: f64,
    /// Relative RMS error of `H = T̃ · B0` against `T · B0` over the error
    /// lights (`None` when not measured).
    pub h_error: Option<f64>,
    pub error_lights: usize,
    pub error_lights_seed: u64,
}

impl CodecSummary {
    /// The summary of `e` (error measured elsewhere).
    pub fn of(e: &Encoded, chosen_by: String, h_error: Option<f64>, lights: usize) -> CodecSummary {
        let entries = (e.n * e.n).max(1) as f64;
        CodecSummary {
            codec: e.kind.name(),
            chosen_by,
            bytes_dense: e.bytes_dense() as u64,
            bytes_sparse: e.bytes_sparse() as u64,
            bytes_index: e.bytes_index() as u64,
            bytes_per_entry: e.bytes_per_entry(),
            bytes_per_entry_dense: e.bytes_dense() as f64 / entries,
            bytes_per_entry_sparse: e.bytes_sparse() as f64 / entries,
            compression_ratio: 12.0 * entries / e.bytes_total().max(1) as f64,
            zero_tile_fraction: e.zero_tile_fraction(),
            h_error,
            error_lights: lights,
            error_lights_seed: ERROR_LIGHTS_SEED,
        }
    }
}

impl std::fmt::Display for CodecSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "codec: {} ({})", self.codec, self.chosen_by)?;
        writeln!(
            f,
            "  bytes per matrix entry: {:.4} dense + {:.4} sparse + {:.4} index = {:.4} \
             ({} + {} + {} bytes; {:.1}x smaller than f32)",
            self.bytes_per_entry_dense,
            self.bytes_per_entry_sparse,
            self.bytes_per_entry - self.bytes_per_entry_dense - self.bytes_per_entry_sparse,
            self.bytes_per_entry,
            self.bytes_dense,
            self.bytes_sparse,
            self.bytes_index,
            self.compression_ratio
        )?;
        writeln!(
            f,
            "  zero tiles skipped: {:.1} %",
            100.0 * self.zero_tile_fraction
        )?;
        match self.h_error {
            Some(e) => write!(
                f,
                "  compression error: relative RMS error of H = T̃·B0 {:.3} % over {} seeded \
                 random lights (seed {:#x})",
                100.0 * e,
                self.error_lights,
                self.error_lights_seed
            ),
            None => write!(f, "  compression error: not measured (no error lights)"),
        }
    }
}

/// What a bake did, for the terminal and for `--json`.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    pub scene: SceneSummary,
    pub device: String,
    pub voxels: VoxelStats,
    pub form_factors: FormFactorStats,
    pub transfer: TransferStats,
    pub reorder: ReorderStats,
    pub codec: CodecSummary,
    pub mesh_map: MeshMapStats,
    /// The bake file written, if any.
    pub output: Option<PathBuf>,
    pub stages: Vec<StageTime>,
}

/// The result of a bake.
pub struct BakeOutput {
    /// The patches kept by the form-factor stage, in matrix order.
    pub patches: Vec<Patch>,
    pub form_factors: FormFactors,
    pub transfer: Transfer,
    /// The reordering: row and column `r` of `encoded` hold patch `order[r]`.
    pub permutation: Permutation,
    pub encoded: Encoded,
    /// The bake file (also written when `output` was given).
    pub file: BakeFile,
    pub report: BakeReport,
}

/// A progress bar on stderr for a stage measured in `unit`s (hidden when
/// stderr is not a terminal).
fn bar(stage: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{prefix:>14} [{bar:40}] {pos}/{len} ({eta} left)")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(stage.to_string());
    bar
}

/// A spinner with the elapsed time for a stage that cannot count its work
/// (hidden when stderr is not a terminal).
fn spinner(stage: &str) -> indicatif::ProgressBar {
    let sp = indicatif::ProgressBar::new_spinner();
    sp.set_style(
        indicatif::ProgressStyle::with_template("{prefix:>14} {spinner} {elapsed}")
            .expect("a valid template"),
    );
    sp.set_prefix(stage.to_string());
    sp.enable_steady_tick(std::time::Duration::from_millis(200));
    sp
}

/// Runs the bake. `progress` receives one line per stage as it starts.
pub fn run(config: &BakeConfig, progress: &mut dyn FnMut(&str)) -> anyhow::Result<BakeOutput> {
    config.validate()?;
    // The output's directory is made now, so that a path that cannot be
    // written fails before the bake rather than after it.
    if let Some(dir) = config.output.as_deref().and_then(Path::parent) {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating the output directory {}", dir.display()))?;
        }
    }
    let gpu = match config.compute {
        ComputeChoice::OpenCl(sel) => Some(Gpu::new(sel).context("opening the OpenCL device")?),
        ComputeChoice::CpuReference => None,
    };
    let backend = backend_of(&gpu);
    let device = device_name(&backend);
    let TransferStages {
        scene,
        vox,
        form_factors: ff,
        patches,
        albedo,
        transfer: tr,
        mut stages,
    } = transfer_stages(config, &backend, progress)?;

    // Stage 5: reorder rows and columns (the same permutation).
    let n = ff.n;
    let method = config.reorder.unwrap_or(ReorderMethod::default_for(n));
    progress(&format!("reordering {n} patches ({method})"));
    let t = Instant::now();
    let t_ref: [&[f32]; 3] = [tr.channel(0), tr.channel(1), tr.channel(2)];
    let sp = spinner("reorder");
    let (perm, reorder_stats) =
        reorder::reorder_with_stats(method, t_ref, n, &patches, backend_of(&gpu))?;
    sp.finish_and_clear();
    let permuted: Vec<Vec<f32>> = tr
        .channels
        .iter()
        .map(|c| perm.apply_symmetric(c, n))
        .collect();
    let tp: [&[f32]; 3] = std::array::from_fn(|c| permuted[c.min(permuted.len() - 1)].as_slice());
    stages.push(StageTime {
        stage: "reorder",
        seconds: t.elapsed().as_secs_f64(),
    });

    // Stage 6: encode, measured against the exact matrix over seeded lights.
    let t = Instant::now();
    let b0_samples: Vec<[Vec<f32>; 3]> = if config.error_lights > 0 {
        progress(&format!(
            "direct light from {} seeded random lights (for the compression error)",
            config.error_lights
        ));
        error_samples(&scene, &patches, config.error_lights)
            .iter()
            .map(|b| std::array::from_fn(|c| perm.apply_vec(&b[c])))
            .collect()
    } else {
        Vec::new()
    };
    let sp = spinner("encode");
    let (encoded, h_error, chosen_by) = match config.codec {
        CodecChoice::Fixed(kind) => {
            progress(&format!("encoding with {kind}"));
            let e = encode::encode(kind, tp, n)?;
            let err = (!b0_samples.is_empty()).then(|| {
                let reference = exact_h(tp, n, &b0_samples);
                encode::h_error(&e, &reference, &b0_samples)
            });
            (e, err, "fixed".to_string())
        }
        CodecChoice::MaxError(max) => {
            progress(&format!(
                "choosing the cheapest codec with H error ≤ {max} ({} candidates)",
                encode::default_candidates().len()
            ));
            let (_, e, err) =
                encode::choose_with(tp, n, &b0_samples, max, &[], &mut |kind, err, bpe| {
                    progress(&format!(
                        "  {kind}: H error {:.3} %, {bpe:.4} bytes/entry",
                        100.0 * err
                    ))
                })?;
            (e, Some(err), format!("max-error {max}"))
        }
    };
    sp.finish_and_clear();
    let summary = CodecSummary::of(&encoded, chosen_by, h_error, b0_samples.len());
    stages.push(StageTime {
        stage: "encode",
        seconds: t.elapsed().as_secs_f64(),
    });

    // Stage 7: the mesh-to-patch map (indices in matrix order, before
    // reordering, as the file's patches).
    progress("mesh-to-patch map");
    let t = Instant::now();
    let mut patch_index_of = vec![None; vox.patches.len()];
    for (m, &v) in ff.kept.iter().enumerate() {
        patch_index_of[v] = Some(m as u32);
    }
    let sp = spinner("mesh map");
    let map = mesh_map::build(&scene, &vox, &patch_index_of)?;
    sp.finish_and_clear();
    stages.push(StageTime {
        stage: "mesh map",
        seconds: t.elapsed().as_secs_f64(),
    });

    // Stage 8: the bake file.
    let options = OptionsRecord {
        record_version: OPTIONS_RECORD_VERSION,
        target_patches: match config.resolution {
            Resolution::Patches(p) => Some(p as u64),
            Resolution::VoxelSize(_) => None,
        },
        voxel_size: vox.stats.voxel_size,
        ff_samples: config.form_factor.samples,
        ff_rays: config.form_factor.rays,
        ff_quadrature_tol: config.form_factor.quadrature_tol,
        bounces: match config.transfer.bounces {
            Bounces::K(k) => BouncesRecord::K(k),
            Bounces::Infinite => BouncesRecord::INFINITE,
        },
        reorder: method.name(),
        codec: encoded.kind.name(),
        codec_choice: summary.chosen_by.clone(),
        error_lights: b0_samples.len() as u64,
        error_lights_seed: ERROR_LIGHTS_SEED,
    };
    let scene_stored = match &config.output {
        Some(out) => stored_scene_path(out, &config.scene),
        None => config.scene.display().to_string(),
    };
    let info = BakeInfo {
        record_version: INFO_RECORD_VERSION,
        generator: format!("radiosity {}", env!("CARGO_PKG_VERSION")),
        scene: scene_stored,
        triangles: scene.triangles.len() as u64,
        vertices: scene.positions.len() as u64,
        patches: n as u64,
        grey: tr.grey,
        spectral_bound: tr.stats.spectral_bound,
        h_error,
        mesh_map_fallbacks: map.stats.fallbacks,
        mesh_map_unmapped: map.stats.unmapped,
    };
    let file = BakeFile {
        options_json: serde_json::to_string(&options).expect("options serialize"),
        scene_hash: SceneHash::of_scene(&scene)?,
        patches: patches.iter().map(PatchRecord::from).collect(),
        permutation: perm.order.clone(),
        codec: encoded.to_blob(),
        mesh_map: map.entries.clone(),
        info_json: serde_json::to_string(&info).expect("info serializes"),
    };
    if let Some(out) = &config.output {
        progress(&format!("writing {}", out.display()));
        let t = Instant::now();
        bakefile::write(out, &file)?;
        stages.push(StageTime {
            stage: "write",
            seconds: t.elapsed().as_secs_f64(),
        });
    }

    if let Some(dir) = &config.export {
        progress(&format!("exporting to {}", dir.display()));
        let t = Instant::now();
        export(
            dir,
            &config.scene,
            scene.bounds(),
            &patches,
            &ff,
            &tr,
            &albedo,
        )?;
        // The matrix as the run time sees it, in the order of patches.csv.
        let inverse = Permutation::from_order(perm.inverse.clone())?;
        let decoded = encoded.decode();
        let mut flat = Vec::with_capacity(3 * n * n);
        for c in &decoded {
            flat.extend_from_slice(&inverse.apply_symmetric(c, n));
        }
        let path = dir.join("T_decoded.npy");
        npy::write_f32(&path, &[3, n, n], &flat)
            .with_context(|| format!("writing {}", path.display()))?;
        stages.push(StageTime {
            stage: "export",
            seconds: t.elapsed().as_secs_f64(),
        });
    }

    Ok(BakeOutput {
        report: BakeReport {
            scene: scene.summary(),
            device,
            voxels: vox.stats,
            form_factors: ff.stats.clone(),
            transfer: tr.stats.clone(),
            reorder: reorder_stats,
            codec: summary,
            mesh_map: map.stats,
            output: config.output.clone(),
            stages,
        },
        patches,
        form_factors: ff,
        transfer: tr,
        permutation: perm,
        encoded,
        file,
    })
}

/// What bake steps 1–4 leave: the scene, its voxel patches, the form
/// factors, the kept patches (matrix order) with their albedos, and the
/// transfer matrix.
pub struct TransferStages {
    pub scene: scene::Scene,
    pub vox: voxelize::Voxelization,
    pub form_factors: FormFactors,
    pub patches: Vec<Patch>,
    pub albedo: Vec<[f32; 3]>,
    pub transfer: Transfer,
    pub stages: Vec<StageTime>,
}

/// Bake steps 1–4 (load → voxelize → form factors → transfer) on
/// `backend`, with progress bars; [`run`] continues from here, and the
/// compression report (`bench::compression`) measures what it returns.
pub fn transfer_stages(
    config: &BakeConfig,
    backend: &Backend,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<TransferStages> {
    let mut stages = Vec::new();

    progress(&format!("loading {}", config.scene.display()));
    let t = Instant::now();
    let scene = scene::load(&config.scene)?;
    stages.push(StageTime {
        stage: "load",
        seconds: t.elapsed().as_secs_f64(),
    });

    progress(&format!("voxelizing on {}", device_name(backend)));
    let t = Instant::now();
    let vox = voxelize::voxelize(&scene, config.resolution, backend)?;
    stages.push(StageTime {
        stage: "voxelize",
        seconds: t.elapsed().as_secs_f64(),
    });

    progress(&format!(
        "form factors for {} patches ({} pairs)",
        vox.patches.len(),
        (vox.patches.len() as u64).pow(2) / 2
    ));
    let t = Instant::now();
    let pb = bar("form factors");
    let ff = form_factor::form_factors(
        &scene,
        &vox.patches,
        &vox.grid,
        &config.form_factor,
        backend,
        &mut |done, total| {
            pb.set_length(total);
            pb.set_position(done);
        },
    )?;
    pb.finish_and_clear();
    stages.push(StageTime {
        stage: "form factors",
        seconds: t.elapsed().as_secs_f64(),
    });
    let patches: Vec<Patch> = ff.kept.iter().map(|&i| vox.patches[i].clone()).collect();
    let albedo: Vec<[f32; 3]> = patches.iter().map(|p| p.albedo.map(|a| a as f32)).collect();

    progress(&format!(
        "transfer matrix, {} bounces, n = {}",
        config.transfer.bounces, ff.n
    ));
    let t = Instant::now();
    let pb = bar("transfer");
    let tr = transfer::transfer(
        &ff.f,
        ff.n,
        &albedo,
        &config.transfer,
        backend,
        &mut |done, total| {
            pb.set_length(total);
            pb.set_position(done);
        },
    )?;
    pb.finish_and_clear();
    stages.push(StageTime {
        stage: "transfer",
        seconds: t.elapsed().as_secs_f64(),
    });

    Ok(TransferStages {
        scene,
        vox,
        form_factors: ff,
        patches,
        albedo,
        transfer: tr,
        stages,
    })
}

/// The device a backend runs on, for reports.
fn device_name(backend: &Backend) -> String {
    match backend {
        Backend::OpenCl(g) => format!(
            "{} ({}, {})",
            g.info().name,
            g.info().kind,
            g.info().platform
        ),
        Backend::Cpu => "CPU reference (f64)".to_string(),
    }
}

/// The backend of an optional device (`Backend` is not `Copy`).
fn backend_of(gpu: &Option<Gpu>) -> Backend<'_> {
    match gpu {
        Some(g) => Backend::OpenCl(g),
        None => Backend::Cpu,
    }
}

/// `B0 = ρ ∘ D + E` (f32, per channel) for `count` seeded random lights
/// ([`direct::random_lights`] with [`ERROR_LIGHTS_SEED`]), direct light with
/// shadows on the CPU, for the patches in matrix order.
pub fn error_samples(scene: &scene::Scene, patches: &[Patch], count: usize) -> Vec<[Vec<f32>; 3]> {
    direct::light_samples(scene, patches, count, ERROR_LIGHTS_SEED)
}

/// The exact `T · B0` in f64 for every sample and channel.
fn exact_h(t: [&[f32]; 3], n: usize, samples: &[[Vec<f32>; 3]]) -> Vec<[Vec<f64>; 3]> {
    samples
        .iter()
        .map(|b| std::array::from_fn(|c| encode::mat_vec(t[c], n, &b[c])))
        .collect()
}

/// Writes the inspection files: `patches.csv` and `patches.png` (the kept
/// patches, in matrix order), `F.npy` (n × n), `T.npy` (3 × n × n,
/// channel-major) and `albedo.npy` (n × 3). Refuses, before writing
/// anything, when `T.npy` would exceed [`form_factor::NPY_MAX_BYTES`].
#[allow(clippy::too_many_arguments)]
fn export(
    dir: &Path,
    scene_path: &Path,
    bounds: ([f32; 3], [f32; 3]),
    patches: &[Patch],
    ff: &FormFactors,
    tr: &Transfer,
    albedo: &[[f32; 3]],
) -> anyhow::Result<()> {
    let n = ff.n;
    let t_bytes = 3 * (n as u64).pow(2) * 4;
    if t_bytes > form_factor::NPY_MAX_BYTES {
        anyhow::bail!(
            "refusing to export T.npy: 3 × {n} × {n} float32 takes {t_bytes} bytes, above the \
             {} byte export limit; use fewer patches or no --export",
            form_factor::NPY_MAX_BYTES
        );
    }
    export_patches(dir, patches)?;
    let camera = scene_camera(scene_path, bounds)?;
    let png = dir.join("patches.png");
    crate::bake::preview::render_patches(patches, &camera, 800, 600)
        .save(&png)
        .with_context(|| format!("writing {}", png.display()))?;
    form_factor::write_f_npy(&dir.join("F.npy"), ff)?;
    let mut t = Vec::with_capacity(3 * n * n);
    for c in 0..3 {
        t.extend_from_slice(tr.channel(c));
    }
    let path = dir.join("T.npy");
    npy::write_f32(&path, &[3, n, n], &t).with_context(|| format!("writing {}", path.display()))?;
    let flat: Vec<f32> = albedo.iter().flatten().copied().collect();
    let path = dir.join("albedo.npy");
    npy::write_f32(&path, &[n, 3], &flat).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The camera of the scene's camera/lights file (`NAME.json` beside
/// `NAME.obj`) if there is one, else a default view of the bounds. A file
/// that exists but is invalid is an error.
pub fn scene_camera(
    scene: &Path,
    bounds: ([f32; 3], [f32; 3]),
) -> anyhow::Result<crate::core::scene_config::Camera> {
    let json = scene.with_extension("json");
    if json.exists() {
        Ok(crate::core::scene_config::load(&json)?.camera)
    } else {
        Ok(crate::bake::preview::default_camera(bounds))
    }
}

/// The header of `patches.csv` (one row per patch, in matrix order).
pub const PATCHES_CSV_HEADER: &str =
    "index,cx,cy,cz,nx,ny,nz,area,albedo_r,albedo_g,albedo_b,emission_r,emission_g,emission_b";

/// Writes `dir/patches.csv`.
pub fn export_patches(dir: &Path, patches: &[Patch]) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join("patches.csv");
    let file =
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let io = |e| anyhow::Error::from(e).context(format!("writing {}", path.display()));
    writeln!(w, "{PATCHES_CSV_HEADER}").map_err(io)?;
    for (i, p) in patches.iter().enumerate() {
        let [cx, cy, cz] = p.centre;
        let [nx, ny, nz] = p.normal;
        let [ar, ag, ab] = p.albedo;
        let [er, eg, eb] = p.emission;
        writeln!(
            w,
            "{i},{cx},{cy},{cz},{nx},{ny},{nz},{},{ar},{ag},{ab},{er},{eg},{eb}",
            p.area
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)?;
    Ok(())
}

impl std::fmt::Display for BakeReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = &self.voxels;
        writeln!(f, "device: {}", self.device)?;
        writeln!(
            f,
            "voxels: size {:.6}, grid {}x{}x{}, {} occupied, {} triangle/voxel pieces ({} candidates, {} slivers of total area {:.3e})",
            v.voxel_size,
            v.grid_dims[0],
            v.grid_dims[1],
            v.grid_dims[2],
            v.occupied_voxels,
            v.pieces,
            v.candidate_pieces,
            v.sliver_pieces,
            v.sliver_area
        )?;
        let per_dir: Vec<String> = crate::core::patch::Direction::ALL
            .iter()
            .map(|d| format!("{} {}", d.name(), v.patches_per_direction[*d as usize]))
            .collect();
        writeln!(f, "patches: {} ({})", v.patches, per_dir.join(", "))?;
        writeln!(
            f,
            "area: patches {:.6e} of scene {:.6e} ({:.2} %); {} staircase groups merged; {} groups facing into solid dropped (area {:.3e}: {}); {} albedo components clamped",
            v.patch_area,
            v.scene_area,
            100.0 * v.patch_area / v.scene_area.max(f64::MIN_POSITIVE),
            v.merged_groups,
            v.covered_groups,
            v.covered_area,
            crate::core::patch::Direction::ALL
                .iter()
                .map(|d| format!("{} {:.3e}", d.name(), v.covered_area_per_direction[*d as usize]))
                .collect::<Vec<_>>()
                .join(", "),
            v.clamped_albedo
        )?;
        if v.search.len() > 1 {
            let tries: Vec<String> = v
                .search
                .iter()
                .map(|(s, n)| format!("{s:.4} -> {n}"))
                .collect();
            writeln!(f, "voxel size search: {}", tries.join(", "))?;
        }
        writeln!(
            f,
            "voxelize detail: pieces {:.3} s (kernels {:.3} s), reduce {:.3} s",
            v.seconds_pieces, v.seconds_kernels, v.seconds_reduce
        )?;
        writeln!(f, "{}", self.form_factors)?;
        writeln!(f, "{}", self.transfer)?;
        let r = &self.reorder;
        writeln!(
            f,
            "reorder: {}, {:.3} s; mean distance between consecutive rows {:.4e} -> {:.4e}",
            r.method, r.seconds, r.adjacent_distance_before, r.adjacent_distance_after
        )?;
        writeln!(f, "{}", self.codec)?;
        let m = &self.mesh_map;
        writeln!(
            f,
            "mesh map: {} vertices, {:.2} patches each on average; {} from a widened search, \
             {} fallbacks ({} blocked by walls), {} unmapped; {:.3} s",
            m.vertices,
            m.mean_patches,
            m.widened,
            m.fallbacks,
            m.fallbacks_blocked,
            m.unmapped,
            m.seconds
        )?;
        writeln!(f)?;
        writeln!(f, "summary")?;
        writeln!(
            f,
            "  n = {} patches, {} bounces, {} reordering, codec {}",
            self.transfer.n, self.transfer.bounces, r.method, self.codec.codec
        )?;
        let total: f64 = self.stages.iter().map(|s| s.seconds).sum();
        write!(f, "  time per stage:")?;
        for s in &self.stages {
            write!(f, " {} {:.2} s;", s.stage, s.seconds)?;
        }
        writeln!(f, " total {total:.2} s")?;
        writeln!(
            f,
            "  bytes per matrix entry: dense {:.4}, sparse {:.4}, total {:.4} (all 3 channels, \
             index included)",
            self.codec.bytes_per_entry_dense,
            self.codec.bytes_per_entry_sparse,
            self.codec.bytes_per_entry
        )?;
        writeln!(
            f,
            "  tiles skipped: {:.1} %",
            100.0 * self.codec.zero_tile_fraction
        )?;
        match self.codec.h_error {
            Some(e) => writeln!(
                f,
                "  compression error: {:.3} % relative RMS of H over {} random lights",
                100.0 * e,
                self.codec.error_lights
            )?,
            None => writeln!(f, "  compression error: not measured")?,
        }
        match &self.output {
            Some(p) => writeln!(f, "  wrote {}", p.display()),
            None => writeln!(f, "  no bake file written (give -o OUT.rad)"),
        }
    }
}

//! The bake pipeline as one call: validated options in, a report out.
//! Stages so far: load → voxelize → form factors → transfer (DESIGN.md
//! section 1, bake steps 1–4); later stages append to [`BakeReport`].

use crate::compute::{DeviceSelection, Gpu};
use crate::error::BakeError;
use crate::form_factor::{self, FormFactorOptions, FormFactorStats, FormFactors};
use crate::npy;
use crate::scene::{self, SceneSummary};
use crate::transfer::{self, Transfer, TransferOptions, TransferStats};
use crate::voxelize::{self, Backend, Patch, Resolution, VoxelStats};
use anyhow::Context as _;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the bake's OpenCL stages run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ComputeChoice {
    /// An OpenCL device (the default).
    OpenCl(DeviceSelection),
    /// The CPU reference implementation of every stage (slow, exact).
    CpuReference,
}

/// The validated options of one bake.
#[derive(Clone, Debug, Serialize)]
pub struct BakeConfig {
    pub scene: PathBuf,
    pub resolution: Resolution,
    pub compute: ComputeChoice,
    pub form_factor: FormFactorOptions,
    pub transfer: TransferOptions,
    /// Directory for inspection files (`patches.csv`, `patches.png`,
    /// `F.npy`, `T.npy`, `albedo.npy`), if asked for.
    pub export: Option<PathBuf>,
}

impl BakeConfig {
    /// Checks option values that do not depend on the scene.
    pub fn validate(&self) -> Result<(), BakeError> {
        match self.resolution {
            Resolution::VoxelSize(s) if !(s.is_finite() && s > 0.0) => Err(BakeError::Options(
                format!("--voxel-size must be a positive finite number, got {s}"),
            )),
            Resolution::Patches(0) => {
                Err(BakeError::Options("--patches must be at least 1".into()))
            }
            _ => Ok(()),
        }
    }
}

/// Time and outcome of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
}

/// What a bake did, for the terminal and for `--json`.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    pub scene: SceneSummary,
    pub device: String,
    pub voxels: VoxelStats,
    pub form_factors: FormFactorStats,
    pub transfer: TransferStats,
    pub stages: Vec<StageTime>,
}

/// The result of a bake.
pub struct BakeOutput {
    /// The patches kept by the form-factor stage, in matrix order.
    pub patches: Vec<Patch>,
    pub form_factors: FormFactors,
    pub transfer: Transfer,
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

/// Runs the bake. `progress` receives one line per stage as it starts.
pub fn run(config: &BakeConfig, progress: &mut dyn FnMut(&str)) -> anyhow::Result<BakeOutput> {
    config.validate()?;
    let mut stages = Vec::new();

    progress(&format!("loading {}", config.scene.display()));
    let t = Instant::now();
    let scene = scene::load(&config.scene)?;
    stages.push(StageTime {
        stage: "load",
        seconds: t.elapsed().as_secs_f64(),
    });

    let gpu = match config.compute {
        ComputeChoice::OpenCl(sel) => Some(Gpu::new(sel).context("opening the OpenCL device")?),
        ComputeChoice::CpuReference => None,
    };
    let backend = match &gpu {
        Some(g) => Backend::OpenCl(g),
        None => Backend::Cpu,
    };
    let device = match &gpu {
        Some(g) => format!(
            "{} ({}, {})",
            g.info().name,
            g.info().kind,
            g.info().platform
        ),
        None => "CPU reference (f64)".to_string(),
    };
    progress(&format!("voxelizing on {device}"));
    let t = Instant::now();
    let vox = voxelize::voxelize(&scene, config.resolution, &backend)?;
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
        &backend,
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
        &backend,
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
            stages,
        },
        patches,
        form_factors: ff,
        transfer: tr,
    })
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
    crate::preview::render_patches(patches, &camera, 800, 600)
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
) -> anyhow::Result<crate::scene_config::Camera> {
    let json = scene.with_extension("json");
    if json.exists() {
        Ok(crate::scene_config::load(&json)?.camera)
    } else {
        Ok(crate::preview::default_camera(bounds))
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
        let per_dir: Vec<String> = crate::voxelize::Direction::ALL
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
            crate::voxelize::Direction::ALL
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
        write!(f, "stages:")?;
        for s in &self.stages {
            write!(f, " {} {:.3} s;", s.stage, s.seconds)?;
        }
        writeln!(f)
    }
}

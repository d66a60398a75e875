//! The bake pipeline as one call: validated options in, a report (and the
//! `.rad` file) out. Stages (docs/design.md section 1, bake steps 1–8): load →
//! voxelize → form factors → transfer → reorder → encode → mesh-to-patch
//! map → write. The compression error of the bake is measured on the way:
//! `H = T̃ · B0` against the exact `T · B0` over seeded random lights
//! ([`radiosity_core::direct::random_lights`], direct light with shadows on the CPU),
//! and `--max-error` uses the same lights to choose the codec.
//!
//! Everything written to the file is deterministic (no timestamps, no
//! timings): the same scene and options give the same bytes. Timings go to
//! the terminal report only.

// NaN-aware tests: `!(x > 0.0)` is true for NaN, which is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod assemble;
pub mod budget;
pub mod cache;
pub mod codec_choice;
pub mod compute;
pub mod config;
pub mod cover;
pub mod cut;
pub mod encode;
pub mod error;
pub mod export;
pub mod facing;
pub mod form_factor;
pub mod gemm;
pub mod mesh_map;
pub mod near_field;
pub mod peak;
pub mod pieces;
pub mod preview;
pub mod probes;
pub mod reorder;
pub mod report;
pub mod solve;
pub mod surface_map;
pub mod trace;
pub mod transfer;
pub mod voxelize;
pub mod winding;

pub use codec_choice::{column_scales, error_samples, Encoding};
pub use config::{BakeConfig, CodecChoice, ComputeChoice, DEFAULT_ERROR_LIGHTS, ERROR_LIGHTS_SEED};
pub use report::{BakeReport, CodecSummary, StageTime};

use crate::compute::Backend;
use crate::compute::Gpu;
use error::BakeError;
use form_factor::FormFactors;
use radiosity_bakefile::codec::Encoded;
use radiosity_bakefile::{self as bakefile, BakeFile, SceneHash};
use radiosity_core::patch::Patch;
use radiosity_core::permutation::Permutation;
use radiosity_core::scene::{self};
use reorder::ReorderMethod;
use report::{bar, spinner};
use std::path::Path;
use std::time::Instant;
use transfer::Transfer;
use voxelize::Resolution;

/// Rays per patch of the patch-count search's count of the patches that see
/// another surface ([`form_factor::rays::seeing_patches`]): 256 rays trace
/// in a few ms per thousand patches, and miss a patch that meets another
/// on 1 % of its hemisphere with probability under 8 %.
const SEEING_PROBE_RAYS: usize = 256;

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

/// Runs the bake. `progress` receives one line per stage as it starts.
pub fn run(config: &BakeConfig, progress: &mut dyn FnMut(&str)) -> Result<BakeOutput, BakeError> {
    config.validate()?;
    let gpu = match config.compute {
        ComputeChoice::OpenCl(sel) => Some(Gpu::new(sel)?),
        ComputeChoice::CpuReference => None,
    };
    let backend = backend_of(&gpu);
    // A requested patch count that cannot fit is refused before anything
    // is spent or written (the voxelization's real count is checked again).
    if let Resolution::Patches(p) = config.resolution {
        budget::check(
            p,
            "the requested patch count",
            budget::host_available(),
            budget_device(&backend, &config.transfer),
            config.export.is_some(),
        )?;
    }
    // The output's directory is made now, so that a path that cannot be
    // written fails before the bake rather than after it.
    if let Some(dir) = config.output.as_deref().and_then(Path::parent) {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|source| BakeError::Io {
                what: "create the output directory",
                path: dir.to_path_buf(),
                source,
            })?;
        }
    }
    let device = backend.device_name();
    let TransferStages {
        scene,
        scene_hash,
        winding,
        vox,
        form_factors: ff,
        facing,
        patches,
        albedo,
        transfer: tr,
        mut stages,
    } = transfer_stages(config, &backend, progress)?;

    // Stage 5: reorder rows and columns (the same permutation).
    let n = ff.n;
    let method = config.reorder.unwrap_or(ReorderMethod::default_for(n));
    progress(&format!("reordering {n} patches ({method})"));
    let (perm, mut permuted, reorder_stats) = timed_stage(&mut stages, "reorder", false, || {
        let t_ref: [&[f32]; 3] = [tr.channel(0), tr.channel(1), tr.channel(2)];
        let (perm, stats) =
            reorder::reorder_with_stats(method, t_ref, n, &patches, backend_of(&gpu))?;
        let permuted: Vec<Vec<f32>> = tr
            .channels
            .iter()
            .map(|c| perm.apply_symmetric(c, n))
            .collect();
        Ok((perm, permuted, stats))
    })?;

    // Stage 6: the codec, chosen and measured (`codec_choice`; its own
    // progress bars).
    let Encoding {
        encoded,
        summary,
        error_lights,
    } = timed_stage(&mut stages, "encode", true, || {
        codec_choice::encode(config, &scene, &patches, &perm, &mut permuted, n, progress)
    })?;

    // Stage 7: what the run time needs per vertex, pixel and neighbour,
    // indices in matrix order (before reordering, as the file's patches).
    let mut patch_index_of = vec![None; vox.patches.len()];
    for (m, &v) in ff.kept.iter().enumerate() {
        patch_index_of[v] = Some(m as u32);
    }
    progress("mesh-to-patch map");
    let map = timed_stage(&mut stages, "mesh map", false, || {
        mesh_map::build(&scene, &vox, &patch_index_of)
    })?;
    progress("surface map and patch sample points");
    let (surface_map, samples, surface_stats) =
        timed_stage(&mut stages, "surface map", false, || {
            surface_map::build(&scene, &vox, &patch_index_of, n)
        })?;
    progress(&format!(
        "near-field correction ({} rays per patch)",
        config.near_field_rays
    ));
    let (near_field, near_field_stats) = timed_stage(&mut stages, "near field", true, || {
        let pb = bar("near field");
        let out = near_field::build(
            &scene,
            &vox,
            &patch_index_of,
            &samples,
            n,
            config.near_field_rays,
            config.near_field_min_form_factor,
            &backend,
            config.form_factor.ray_device,
            &mut |done, total| {
                pb.set_length(total);
                pb.set_position(done);
            },
        );
        pb.finish_and_clear();
        out
    })?;
    if let Some(stage) = stages.last_mut() {
        stage.device = rays_device(&backend, config.form_factor.ray_device);
    }

    let (probes, probe_stats) = if config.probes.enabled() {
        progress(&format!(
            "irradiance probes ({} rays each)",
            config.probes.rays
        ));
        timed_stage(&mut stages, "probes", false, || {
            probes::build(&scene, &vox, &patch_index_of, &config.probes)
        })?
    } else {
        Default::default()
    };

    // Stage 8: the bake file (`assemble`), written, and the inspection
    // files (`export`).
    let file = assemble::bake_file(assemble::Parts {
        config,
        scene: &scene,
        scene_hash,
        voxel_size: vox.stats.voxel_size,
        reorder: method.name(),
        encoded: &encoded,
        summary: &summary,
        error_lights,
        twinned: &winding.twinned,
        transfer: &tr,
        mesh_map: &map,
        patches: &patches,
        permutation: &perm,
        surface_map,
        samples,
        near_field,
        sky: (&ff.sky, config.form_factor.rays_per_patch),
        probes,
    });
    if let Some(out) = &config.output {
        progress(&format!("writing {}", out.display()));
        timed_stage(&mut stages, "write", false, || {
            Ok(bakefile::write(out, &file)?)
        })?;
    }
    if let Some(dir) = &config.export {
        progress(&format!("exporting to {}", dir.display()));
        timed_stage(&mut stages, "export", false, || {
            export::export_bake(
                dir,
                export::Bake {
                    scene_path: &config.scene,
                    scene: &scene,
                    vox: &vox,
                    patch_index_of: &patch_index_of,
                    patches: &patches,
                    form_factors: &ff,
                    transfer: &tr,
                    albedo: &albedo,
                    encoded: &encoded,
                    permutation: &perm,
                },
            )
        })?;
    }

    Ok(BakeOutput {
        report: BakeReport {
            scene: scene.summary(),
            device,
            voxels: vox.stats,
            form_factors: ff.stats.clone(),
            facing,
            winding,
            transfer: tr.stats.clone(),
            reorder: reorder_stats,
            codec: summary,
            mesh_map: map.stats,
            surface_map: surface_stats,
            near_field: near_field_stats,
            probes: probe_stats,
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

/// Runs `f` as the stage `name`, its time recorded in `stages`, with a
/// spinner while it runs unless the stage draws its own progress bars
/// (`bars`).
fn timed_stage<T>(
    stages: &mut Vec<StageTime>,
    name: &'static str,
    bars: bool,
    f: impl FnOnce() -> Result<T, BakeError>,
) -> Result<T, BakeError> {
    let t = Instant::now();
    let sp = (!bars).then(|| spinner(name));
    let out = f();
    if let Some(sp) = sp {
        sp.finish_and_clear();
    }
    // The stages timed here all run on the host.
    stages.push(StageTime {
        stage: name,
        seconds: t.elapsed().as_secs_f64(),
        device: report::host_threads(),
    });
    out
}

/// Where a stage casting rays from the real surfaces runs: the device's
/// traversal with the host drawing and classifying the rays, or the host.
fn rays_device(backend: &Backend, choice: form_factor::RayDevice) -> String {
    match form_factor::tracer::ray_gpu(backend, choice) {
        Some(_) => format!(
            "{} (traversal) and {}",
            backend.device_name(),
            report::host_threads()
        ),
        None => report::host_threads(),
    }
}

/// What bake steps 1–4 leave: the scene, its voxel patches, the form
/// factors, the kept patches (matrix order) with their albedos, and the
/// transfer matrix.
pub struct TransferStages {
    /// The scene baked (with back sides when two-sided) and the hash of the
    /// scene as loaded (what the file records).
    pub scene: scene::Scene,
    pub scene_hash: SceneHash,
    /// What the winding check changed (nothing when two-sided).
    pub winding: winding::Winding,
    pub vox: voxelize::Voxelization,
    pub form_factors: FormFactors,
    pub facing: facing::Facing,
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
) -> Result<TransferStages, BakeError> {
    let mut stages = Vec::new();

    progress(&format!("loading {}", config.scene.display()));
    let t = Instant::now();
    let loaded = scene::load(&config.scene)?;
    // The file records the scene as loaded; two-sided bakes work on its
    // doubled form, which the run time rebuilds from the option.
    let scene_hash = SceneHash::of_scene(&loaded)?;
    stages.push(StageTime {
        stage: "load",
        seconds: t.elapsed().as_secs_f64(),
        device: report::host_threads(),
    });
    // Faces seen from both sides (wound the wrong way, or single-sided in
    // open space) given a back side (module `winding`); two-sided bakes
    // have back sides everywhere.
    // Double-sided materials (glTF's `doubleSided`) have back sides
    // whatever the check finds, as wound or not.
    let double_sided: Vec<u32> = (0..loaded.triangles.len() as u32)
        .filter(|&t| loaded.materials[loaded.triangle_material[t as usize] as usize].double_sided)
        .collect();
    let (scene, winding) = if config.two_sided {
        (loaded.with_back_sides(), winding::Winding::default())
    } else if config.as_wound {
        let w = winding::Winding {
            double_sided: double_sided.len(),
            twinned: double_sided,
            ..winding::Winding::default()
        };
        (loaded.with_back_sides_of(&w.twinned), w)
    } else {
        progress("checking each face's winding");
        let mut w = winding::check(&loaded);
        if !w.is_empty() {
            progress(&w.to_string());
        }
        if !double_sided.is_empty() {
            // The probes' list leaves out what double-sided adds: its
            // area and materials stay the probes' findings.
            let mut probed = std::mem::take(&mut w.twinned);
            probed.retain(|t| double_sided.binary_search(t).is_err());
            w.twinned_area = probed
                .iter()
                .map(|&t| loaded.triangle_area(t as usize))
                .sum();
            w.twinned = probed;
            w.double_sided = double_sided.len();
            w.twinned.extend(&double_sided);
            w.twinned.sort_unstable();
            progress(&format!(
                "{} triangles of double-sided materials get a back side",
                double_sided.len()
            ));
        }
        stages.push(StageTime {
            stage: "winding",
            seconds: w.seconds,
            device: report::host_threads(),
        });
        (loaded.with_back_sides_of(&w.twinned), w)
    };

    progress(&format!("voxelizing on {}", backend.device_name()));
    let t = Instant::now();
    // A patch-count target is met on the patches the form factors keep,
    // those that see another surface (a quarter of Sponza's see only the
    // sky and would be removed: asked for 4,000, it kept 2,782); a scene
    // where none does (one open plane) counts them all.
    let count = |v: &voxelize::Voxelization| match form_factor::rays::seeing_patches(
        &scene,
        v,
        SEEING_PROBE_RAYS,
    ) {
        0 => v.stats.patches,
        k => k,
    };
    let vox = voxelize::voxelize_counting(&scene, config.resolution, backend, &count)?;
    stages.push(StageTime {
        stage: "voxelize",
        seconds: t.elapsed().as_secs_f64(),
        device: backend.device_name(),
    });
    // The form factors run over every voxel patch; the later stages over
    // those that see another surface, which the search counted at the
    // chosen size (all of them when a voxel size was given). Both are
    // checked now, before the form factors' time is spent, and the later
    // stages again on the exact count the form factors keep.
    budget::check_form_factors(vox.patches.len(), budget::host_available())?;
    let expected_kept = vox
        .stats
        .search
        .iter()
        .rev()
        .find(|&&(size, _)| size == vox.stats.voxel_size)
        .map(|&(_, counted)| counted as usize)
        .filter(|&k| k > 0)
        .unwrap_or(vox.patches.len())
        .min(vox.patches.len());
    budget::check(
        expected_kept,
        "the count of voxel patches that see another surface",
        budget::host_available(),
        budget_device(backend, &config.transfer),
        config.export.is_some(),
    )?;

    progress(&format!(
        "form factors for {} patches ({} pairs)",
        vox.patches.len(),
        (vox.patches.len() as u64).pow(2) / 2
    ));
    let t = Instant::now();
    let pb = bar("form factors");
    let ff = form_factor::of_voxelization(
        &scene,
        &vox,
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
        device: match config.form_factor.method {
            form_factor::FormFactorMethod::Rays => {
                rays_device(backend, config.form_factor.ray_device)
            }
            form_factor::FormFactorMethod::Contour => backend.device_name(),
        },
    });
    let facing = facing::check(&scene, &vox, &ff, config.two_sided)?;
    for w in &facing.warnings {
        progress(&format!("warning: {w}"));
    }
    let patches: Vec<Patch> = ff.kept.iter().map(|&i| vox.patches[i].clone()).collect();
    let albedo: Vec<[f32; 3]> = patches.iter().map(|p| p.albedo.map(|a| a as f32)).collect();
    budget::check(
        ff.n,
        "the patch count the form factors keep",
        budget::host_available(),
        budget_device(backend, &config.transfer),
        config.export.is_some(),
    )?;

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
        device: backend.device_name(),
    });

    Ok(TransferStages {
        scene,
        scene_hash,
        winding,
        vox,
        form_factors: ff,
        facing,
        patches,
        albedo,
        transfer: tr,
        stages,
    })
}

/// The transfer stage's share of the budget on `backend` with `options`:
/// the padded matrices it keeps on the device ([`transfer::cl_matrices`]).
fn budget_device<'a>(
    backend: &'a Backend,
    options: &transfer::TransferOptions,
) -> budget::Device<'a> {
    match backend {
        Backend::Cpu => budget::Device::CpuReference,
        Backend::OpenCl(g) => budget::Device::OpenCl {
            info: g.info(),
            matrices: transfer::cl_matrices(options),
        },
    }
}

/// The backend of an optional device (`Backend` is not `Copy`).
fn backend_of(gpu: &Option<Gpu>) -> Backend<'_> {
    match gpu {
        Some(g) => Backend::OpenCl(g),
        None => Backend::Cpu,
    }
}

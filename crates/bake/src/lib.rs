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

pub mod budget;
pub mod cache;
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
pub mod pieces;
pub mod preview;
pub mod reorder;
pub mod report;
pub mod solve;
pub mod surface_map;
pub mod transfer;
pub mod voxelize;
pub mod winding;

pub use config::{BakeConfig, CodecChoice, ComputeChoice, DEFAULT_ERROR_LIGHTS, ERROR_LIGHTS_SEED};
pub use report::{BakeReport, CodecSummary, StageTime};

use crate::compute::Backend;
use crate::compute::Gpu;
use anyhow::Context as _;
use form_factor::FormFactors;
use radiosity_bakefile::baked::stored_scene_path;
use radiosity_bakefile::codec::Encoded;
use radiosity_bakefile::records::{
    BakeInfo, BouncesRecord, OptionsRecord, INFO_RECORD_VERSION, OPTIONS_RECORD_VERSION,
};
use radiosity_bakefile::{self as bakefile, BakeFile, PatchRecord, SceneHash};
use radiosity_core::direct;
use radiosity_core::npy;
use radiosity_core::patch::Patch;
use radiosity_core::permutation::Permutation;
use radiosity_core::scene::{self};
use rayon::prelude::*;
use reorder::ReorderMethod;
use report::{bar, spinner};
use std::path::Path;
use std::time::Instant;
use transfer::{Bounces, Transfer};
use voxelize::Resolution;

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
pub fn run(config: &BakeConfig, progress: &mut dyn FnMut(&str)) -> anyhow::Result<BakeOutput> {
    config.validate()?;
    let gpu = match config.compute {
        ComputeChoice::OpenCl(sel) => Some(Gpu::new(sel).context("opening the OpenCL device")?),
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
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating the output directory {}", dir.display()))?;
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
    let t = Instant::now();
    let t_ref: [&[f32]; 3] = [tr.channel(0), tr.channel(1), tr.channel(2)];
    let sp = spinner("reorder");
    let (perm, reorder_stats) =
        reorder::reorder_with_stats(method, t_ref, n, &patches, backend_of(&gpu))?;
    sp.finish_and_clear();
    let mut permuted: Vec<Vec<f32>> = tr
        .channels
        .iter()
        .map(|c| perm.apply_symmetric(c, n))
        .collect();
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
    // Column scales (`Encoded::col_scale`): each column divided by its
    // patch's area relative to the largest. They are a second setting
    // beside the codec's, tried where the error is measured and the codec
    // is a log one (a plain f32 or f16 matrix would only gain a rounding):
    // first the plain matrix, then, in place, `T' = T diag(1/s)` with the
    // samples `s ∘ B0`; the cheaper result within the bound is kept, at
    // equal bytes the smaller error (for a fixed codec, the smaller
    // error). On Sponza at 3,946 patches the scales halve BC1's error at a
    // given top fraction; at 12,872, and on the interior, they raise it
    // (docs/runtime.md).
    let scales =
        column_scales(&perm.apply_vec(&patches.iter().map(|p| p.area).collect::<Vec<f64>>()));
    let scaled_samples: Vec<[Vec<f32>; 3]> = b0_samples
        .iter()
        .map(|b| radiosity_bakefile::codec::scaled_input([&b[0], &b[1], &b[2]], &scales))
        .collect();
    let sp = spinner("encode");
    let (encoded, h_error, chosen_by) = match config.codec {
        CodecChoice::Fixed(kind) => {
            progress(&format!("encoding with {kind}"));
            let (e, err) = {
                let tp = channels_of(&permuted);
                let e = encode::encode(kind, tp, n)?;
                let err = (!b0_samples.is_empty()).then(|| {
                    let reference = exact_h(tp, n, &b0_samples);
                    encode::h_error(&e, &reference, &b0_samples)
                });
                (e, err)
            };
            let (e, err) = match err {
                Some(err0) if kind.log_params().is_some() => {
                    scale_columns(&mut permuted, &scales, n);
                    let tp = channels_of(&permuted);
                    let mut e1 = encode::encode(kind, tp, n)?;
                    let reference = exact_h(tp, n, &scaled_samples);
                    let err1 = encode::h_error(&e1, &reference, &scaled_samples);
                    progress(&format!(
                        "  H error {:.3} %, with columns scaled by patch area {:.3} %",
                        100.0 * err0,
                        100.0 * err1
                    ));
                    if err1 < err0 {
                        e1.col_scale = scales;
                        (e1, Some(err1))
                    } else {
                        (e, Some(err0))
                    }
                }
                other => (e, other),
            };
            (e, err, "fixed".to_string())
        }
        CodecChoice::MaxError(max) => {
            progress(&format!(
                "choosing the cheapest codec with H error ≤ {max} ({} candidates, then with \
                 columns scaled by patch area)",
                encode::default_candidates().len()
            ));
            let (k0, e0, err0) = encode::choose_with(
                channels_of(&permuted),
                n,
                &b0_samples,
                max,
                &[],
                &mut |kind, err, bpe| {
                    progress(&format!(
                        "  {kind}: H error {:.3} %, {bpe:.4} bytes/entry",
                        100.0 * err
                    ))
                },
            )?;
            // Scaled, the log settings expected to cost no more than the
            // plain choice.
            let cheaper = encode::measure::log_candidates_no_dearer_than(k0);
            let scaled = if cheaper.is_empty() {
                None
            } else {
                scale_columns(&mut permuted, &scales, n);
                match encode::choose_with(
                    channels_of(&permuted),
                    n,
                    &scaled_samples,
                    max,
                    &cheaper,
                    &mut |kind, err, bpe| {
                        progress(&format!(
                            "  {kind}, columns scaled: H error {:.3} %, {bpe:.4} bytes/entry",
                            100.0 * err
                        ))
                    },
                ) {
                    Ok(chosen) => Some(chosen),
                    // No scaled setting within the bound: the plain one stays.
                    Err(encode::measure::ChooseError::NoCandidate { .. }) => None,
                    Err(e) => return Err(e.into()),
                }
            };
            match scaled {
                // The cheaper matrix, or at equal bytes the smaller error;
                // the scales' 4 bytes per patch (4/n bytes per entry) are
                // not held against it.
                Some((_, mut e1, err1))
                    if e1.bytes_total() < e0.bytes_total()
                        || (e1.bytes_total() == e0.bytes_total() && err1 < err0) =>
                {
                    e1.col_scale = scales;
                    (e1, Some(err1), format!("max-error {max}, columns scaled"))
                }
                _ => (e0, Some(err0), format!("max-error {max}")),
            }
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
    progress("surface map and patch sample points");
    let t = Instant::now();
    let sp = spinner("surface map");
    let (surface_map, samples, surface_stats) =
        surface_map::build(&scene, &vox, &patch_index_of, n)?;
    sp.finish_and_clear();
    stages.push(StageTime {
        stage: "surface map",
        seconds: t.elapsed().as_secs_f64(),
    });
    progress(&format!(
        "near-field correction ({} rays per patch)",
        config.near_field_rays
    ));
    let sp = spinner("near field");
    let (near_field, near_field_stats) = near_field::build(
        &scene,
        &vox,
        &patch_index_of,
        &samples,
        n,
        config.near_field_rays,
        config.near_field_min_form_factor,
    )?;
    sp.finish_and_clear();
    stages.push(StageTime {
        stage: "near field",
        seconds: near_field_stats.seconds,
    });

    // Stage 8: the bake file.
    let options = OptionsRecord {
        record_version: OPTIONS_RECORD_VERSION,
        target_patches: match config.resolution {
            Resolution::Patches(p) => Some(p as u64),
            Resolution::VoxelSize(_) => None,
        },
        voxel_size: vox.stats.voxel_size,
        ff_method: config.form_factor.method.name().into(),
        ff_rays_per_patch: config.form_factor.rays_per_patch,
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
        two_sided: config.two_sided,
        twinned: winding.twinned.clone(),
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
        scene_hash,
        patches: patches.iter().map(PatchRecord::from).collect(),
        permutation: perm.order.clone(),
        codec: encoded.to_blob(),
        mesh_map: map.entries.clone(),
        surface_map,
        samples,
        near_field,
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
        let geo = pieces::geometry(&scene, &vox);
        let owner: Vec<Option<u32>> = vox
            .pieces
            .iter()
            .map(|p| p.patch.and_then(|v| patch_index_of[v as usize]))
            .collect();
        export::export(
            dir,
            &config.scene,
            scene.bounds(),
            &patches,
            (&geo, &owner),
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
            facing,
            winding,
            transfer: tr.stats.clone(),
            reorder: reorder_stats,
            codec: summary,
            mesh_map: map.stats,
            surface_map: surface_stats,
            near_field: near_field_stats,
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
) -> anyhow::Result<TransferStages> {
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
        });
        (loaded.with_back_sides_of(&w.twinned), w)
    };

    progress(&format!("voxelizing on {}", backend.device_name()));
    let t = Instant::now();
    let vox = voxelize::voxelize(&scene, config.resolution, backend)?;
    stages.push(StageTime {
        stage: "voxelize",
        seconds: t.elapsed().as_secs_f64(),
    });
    budget::check(
        vox.patches.len(),
        "the voxelization's patch count",
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
    });
    let facing = facing::check(&scene, &vox, &ff, config.two_sided)?;
    for w in &facing.warnings {
        progress(&format!("warning: {w}"));
    }
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

/// `B0 = ρ ∘ D + E` (f32, per channel) for `count` seeded random lights
/// ([`direct::random_lights`] with [`ERROR_LIGHTS_SEED`]), direct light with
/// shadows on the CPU, for the patches in matrix order.
pub fn error_samples(scene: &scene::Scene, patches: &[Patch], count: usize) -> Vec<[Vec<f32>; 3]> {
    direct::light_samples(scene, patches, count, ERROR_LIGHTS_SEED)
}

/// The column scales of a matrix whose patches have areas `area` (matrix
/// order): each area relative to the largest, so in (0, 1] (a patch of
/// zero area, which the voxelizer does not keep, would get the smallest
/// positive f32 rather than 0).
pub fn column_scales(area: &[f64]) -> Vec<f32> {
    let max = area.iter().cloned().fold(0.0f64, f64::max);
    if !(max > 0.0 && max.is_finite()) {
        return vec![1.0; area.len()];
    }
    area.iter()
        .map(|&a| ((a / max) as f32).max(f32::MIN_POSITIVE))
        .collect()
}

/// The three channels of a matrix held as 1 or 3 vectors.
fn channels_of(m: &[Vec<f32>]) -> [&[f32]; 3] {
    std::array::from_fn(|c| m[c.min(m.len() - 1)].as_slice())
}

/// Divides each column `j` of the n × n row-major channels `m` by `s[j]`,
/// in place.
fn scale_columns(m: &mut [Vec<f32>], s: &[f32], n: usize) {
    for c in m {
        c.par_chunks_mut(n.max(1)).for_each(|row| {
            for (v, s) in row.iter_mut().zip(s) {
                *v /= s;
            }
        });
    }
}

/// The exact `T · B0` in f64 for every sample and channel.
fn exact_h(t: [&[f32]; 3], n: usize, samples: &[[Vec<f32>; 3]]) -> Vec<[Vec<f64>; 3]> {
    samples
        .iter()
        .map(|b| std::array::from_fn(|c| encode::mat_vec(t[c], n, &b[c])))
        .collect()
}

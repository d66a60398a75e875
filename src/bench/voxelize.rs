//! `radiosity bench voxelize`: the voxelization kernel against its CPU
//! reference at several voxel sizes, in the same run.

use super::{best_of, memory_bandwidth};
use crate::bake::voxelize;
use crate::core::compute::{Backend, DeviceSelection, Gpu};
use crate::core::scene;
use anyhow::Context as _;
use std::fmt::Write as _;
use std::path::Path;

/// Voxelization on OpenCL against the CPU reference at each voxel size.
/// Returns a printable table.
pub fn run(
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

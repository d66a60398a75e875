//! Benchmarks behind `radiosity bench`: every time is printed beside its
//! error against a named reference (here: the f64 CPU reference, measured
//! in the same run), and throughput beside the machine's measured memory
//! bandwidth. Timings on a shared 2-core machine are noisy; compare the
//! ratios within one run.

use crate::compute::{DeviceSelection, Gpu};
use crate::scene;
use crate::voxelize::{self, Backend};
use anyhow::Context as _;
use std::fmt::Write as _;
use std::path::Path;
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

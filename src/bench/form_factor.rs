//! `radiosity bench form-factors`: form factors on OpenCL and on the CPU
//! reference at several patch counts, in the same run. The rays method
//! (the bake's default) times the device's traversal (`kernels/trace.cl`)
//! against the CPU's native one on the same rays and checks that they
//! give the same matrix; the contour method times its kernel against its
//! f64 reference.

use crate::bake::form_factor::{
    compare, form_factors, of_voxelization, FormFactorMethod, FormFactorOptions, RayDevice,
};
use crate::core::compute::{Backend, Gpu};
use std::path::Path;

/// The form-factor benchmark behind `radiosity bench form-factors`: for
/// each target patch count, voxelize `scene_path` (OpenCL), compute `F` on
/// OpenCL and, when `cpu_reference`, on the CPU reference in the same run,
/// and tabulate pairs/s, rays/s and the difference. Returns the table.
pub fn run(
    scene_path: &Path,
    targets: &[usize],
    options: &FormFactorOptions,
    selection: crate::core::compute::DeviceSelection,
    cpu_reference: bool,
) -> anyhow::Result<String> {
    use anyhow::Context as _;
    let scene = crate::core::scene::load(scene_path)?;
    let gpu = Gpu::new(selection).context("opening the OpenCL device")?;
    let inputs = Inputs {
        scene_path,
        scene: &scene,
        gpu: &gpu,
        targets,
        options,
        cpu_reference,
    };
    match options.method {
        FormFactorMethod::Rays => inputs.rays(),
        FormFactorMethod::Contour => inputs.contour(),
    }
}

/// What both methods' tables are made from.
struct Inputs<'a> {
    scene_path: &'a Path,
    scene: &'a crate::core::scene::Scene,
    gpu: &'a Gpu,
    targets: &'a [usize],
    options: &'a FormFactorOptions,
    cpu_reference: bool,
}

impl Inputs<'_> {
    /// The rays method's table (module doc): per target patch count, the
    /// rays traced on the device and on the CPU, their times and rays per
    /// second, and how many entries differ (0: the kernel's hits are the
    /// CPU's bit for bit).
    fn rays(&self) -> anyhow::Result<String> {
        use std::fmt::Write as _;
        let mut out = String::new();
        writeln!(
            out,
            "rays form factors of {} ({} triangles), {} rays per patch: traversal on {} ({}, {}) against the CPU's (rayon on {} threads, AVX); the host draws and classifies the rays in both",
            self.scene_path.display(),
            self.scene.triangles.len(),
            self.options.rays_per_patch,
            self.gpu.info().name,
            self.gpu.info().kind,
            self.gpu.info().platform,
            rayon::current_num_threads()
        )?;
        writeln!(
            out,
            "| patches | kept | rays cast | device (s) | of which kernels (s) | device rays/s | CPU (s) | CPU rays/s | device / CPU time | entries differing |"
        )?;
        writeln!(out, "|---|---|---|---|---|---|---|---|---|---|")?;
        for &target in self.targets {
            let vox = crate::bake::voxelize::voxelize(
                self.scene,
                crate::bake::voxelize::Resolution::Patches(target),
                &Backend::OpenCl(self.gpu),
            )?;
            let on = |backend: &Backend, ray_device| {
                let o = FormFactorOptions {
                    ray_device,
                    ..self.options.clone()
                };
                of_voxelization(self.scene, &vox, &o, backend, &mut |_, _| {})
            };
            let dev = on(&Backend::OpenCl(self.gpu), RayDevice::Device)?;
            let s = &dev.stats;
            let cpu_cells = if self.cpu_reference {
                let cpu = on(&Backend::Cpu, RayDevice::Cpu)?;
                let differ = dev
                    .f
                    .iter()
                    .zip(&cpu.f)
                    .filter(|(a, b)| a.to_bits() != b.to_bits())
                    .count()
                    + dev.f.len().abs_diff(cpu.f.len());
                format!(
                    "{:.2} | {:.3e} | {:.2} | {}",
                    cpu.stats.seconds_pairs,
                    cpu.stats.rays_per_second,
                    s.seconds_pairs / cpu.stats.seconds_pairs.max(1e-9),
                    differ
                )
            } else {
                "- | - | - | -".to_string()
            };
            writeln!(
                out,
                "| {} | {} | {} | {:.2} | {:.2} | {:.3e} | {} |",
                s.patches,
                s.kept,
                s.rays_cast,
                s.seconds_pairs,
                s.seconds_kernels,
                s.rays_per_second,
                cpu_cells
            )?;
        }
        Ok(out)
    }

    /// The contour method's table: the kernel against its f64 reference.
    fn contour(&self) -> anyhow::Result<String> {
        use std::fmt::Write as _;
        let mut out = String::new();
        writeln!(
            out,
            "form factors of {} ({} triangles) on {} ({}); samples {}, rays {}, quadrature_tol {}; CPU reference: f64, rayon on {} threads",
            self.scene_path.display(),
            self.scene.triangles.len(),
            self.gpu.info().name,
            self.gpu.info().platform,
            self.options.samples,
            self.options.rays,
            self.options.quadrature_tol,
            rayon::current_num_threads()
        )?;
        writeln!(
            out,
            "| voxel size | patches | removed | pairs | evaluated | back-facing | cert. blocked | rays | OpenCL (s) | pairs/s | rays/s | CPU ref (s) | CPU pairs/s | CPU rays/s | max row sum before corr. | rows corrected | max abs ΔF | rel. Frobenius ΔF | max Δ row sum |"
        )?;
        writeln!(
            out,
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        )?;
        for &target in self.targets {
            let vox = crate::bake::voxelize::voxelize(
                self.scene,
                crate::bake::voxelize::Resolution::Patches(target),
                &Backend::OpenCl(self.gpu),
            )?;
            let cl = form_factors(
                self.scene,
                &vox.patches,
                &vox.grid,
                self.options,
                &Backend::OpenCl(self.gpu),
                &mut |_, _| {},
            )?;
            let s = &cl.stats;
            let (cpu_cells, diff_cells) = if self.cpu_reference {
                let cpu = form_factors(
                    self.scene,
                    &vox.patches,
                    &vox.grid,
                    self.options,
                    &Backend::Cpu,
                    &mut |_, _| {},
                )?;
                let c = compare(&cl, &cpu)?;
                (
                    format!(
                        "{:.2} | {:.3e} | {:.3e}",
                        cpu.stats.seconds_pairs,
                        cpu.stats.pairs_per_second,
                        cpu.stats.rays_per_second
                    ),
                    format!(
                        "{:.2e} | {:.2e} | {:.2e}",
                        c.max_abs_diff, c.rel_frobenius, c.max_row_sum_diff
                    ),
                )
            } else {
                ("- | - | -".to_string(), "- | - | -".to_string())
            };
            writeln!(
                out,
                "| {:.4} | {} | {} | {} | {} | {} | {} | {} | {:.2} | {:.3e} | {:.3e} | {} | {:.6} | {} | {} |",
                vox.grid.size,
                s.patches,
                s.removed_patches,
                s.pairs_total,
                s.pairs_evaluated,
                s.skipped_backfacing,
                s.skipped_blocked,
                s.rays_cast,
                s.seconds_pairs,
                s.pairs_per_second,
                s.rays_per_second,
                cpu_cells,
                s.max_row_sum_before,
                s.row_corrections,
                diff_cells
            )?;
        }
        Ok(out)
    }
}

//! The device's measured f32 FMA rate (`kernels/peak.cl`), the peak the
//! benchmarks state their throughput against: a vendor's figure is a clock
//! and a unit count, not what this device, driver and compiler reach. Each
//! work-item runs [`CHAINS`] independent chains of `VW`-wide fused
//! multiply-adds; the rate is `2 · CHAINS · VW · iterations · work-items`
//! over the kernel's device time, best of a few launches.
//!
//! [`reference()`] computes one work-item's output on the CPU in the
//! kernel's order; `tests/transfer.rs` compares every work-item bit for bit
//! (fma is exactly rounded in OpenCL and in Rust's `mul_add`).

use crate::compute::{round_up, Access, Gpu};
use opencl3::kernel::ExecuteKernel;
use opencl3::types::{cl_float, cl_uint};
use radiosity_core::error::ClError;
use serde::Serialize;

/// The kernel's source.
pub const SOURCE: &str = include_str!("../kernels/peak.cl");

/// Independent chains per work-item (`CHAINS` in the kernel).
pub const CHAINS: usize = 8;

/// The chains' multiplier and addend: `a ← a·M + C` converges to
/// `C / (1 − M) = 1`, so no value overflows or turns subnormal.
pub const M: f32 = 0.999;
pub const C: f32 = 0.001;

/// A measured peak.
#[derive(Clone, Debug, Serialize)]
pub struct Peak {
    /// f32 FMA operations as flops (2 per FMA) per second.
    pub gflops: f64,
    pub vector_width: usize,
    pub work_items: usize,
    pub iterations: u32,
    /// The work-items' outputs of the last launch.
    #[serde(skip)]
    pub outputs: Vec<f32>,
}

/// The vector width the kernel uses on a device: its native f32 width
/// (16 on AVX-512 under PoCL, 8 on AVX2), at least 4.
fn vector_width(gpu: &Gpu) -> usize {
    match crate::gemm::native_float_width(gpu) {
        w if w >= 16 => 16,
        w if w >= 8 => 8,
        _ => 4,
    }
}

/// Measures the peak: `iterations` per work-item, enough work-items to
/// fill the device (2,048 per compute unit on a GPU, 4 on a CPU), best of
/// `repeat` launches.
pub fn measure(gpu: &Gpu, iterations: u32, repeat: usize) -> Result<Peak, ClError> {
    let vw = vector_width(gpu);
    let program = gpu.build("peak.cl", SOURCE, &format!("-D VW={vw}"))?;
    let kernel = gpu.kernel(&program, "fma_peak")?;
    let info = gpu.info();
    let (per_unit, preferred) = if info.kind == "GPU" {
        (2048, 256)
    } else {
        (4, 1)
    };
    let local = gpu.local_size(&kernel, preferred);
    let items = round_up(info.compute_units.max(1) as usize * per_unit, local);
    let out = gpu.buffer::<cl_float>("peak outputs", items, Access::WriteOnly)?;
    let mut best = f64::INFINITY;
    for _ in 0..repeat.max(1) {
        let seconds = gpu.timed("fma_peak", || unsafe {
            // SAFETY: the kernel writes `items` floats into a buffer of
            // `items`.
            ExecuteKernel::new(&kernel)
                .set_arg(&out)
                .set_arg(&(iterations as cl_uint))
                .set_arg(&M)
                .set_arg(&C)
                .set_global_work_size(items)
                .set_local_work_size(local)
                .enqueue_nd_range(gpu.queue())
        })?;
        best = best.min(seconds);
    }
    let outputs = gpu.download("peak outputs", &out, items)?;
    let flop = 2.0 * (CHAINS * vw) as f64 * iterations as f64 * items as f64;
    Ok(Peak {
        gflops: flop / best.max(1e-12) * 1e-9,
        vector_width: vw,
        work_items: items,
        iterations,
        outputs,
    })
}

/// Work-item `gid`'s output (the kernel's order; module doc).
pub fn reference(gid: usize, vector_width: usize, iterations: u32) -> f32 {
    let mut s = 0.0f32;
    let mut a: Vec<f32> = (0..CHAINS * vector_width)
        .map(|k| ((gid * CHAINS * vector_width + k) as f32) * (1.0 / 1_048_576.0))
        .collect();
    for _ in 0..iterations {
        for x in &mut a {
            *x = x.mul_add(M, C);
        }
    }
    for x in a {
        s += x;
    }
    s
}

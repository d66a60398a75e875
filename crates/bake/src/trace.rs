//! Nearest hits of many rays on an OpenCL device: the host of
//! `kernels/trace.cl`, which follows [`Bvh4::closest_hit`] in f64 step by
//! step, so the device's answer for a segment is the CPU's bit for bit
//! (`tests/trace.rs` checks it on hostile generated scenes and on Sponza).
//!
//! The stages that cast rays from the real surfaces (the form factors, the
//! near field) generate their rays on the host and classify the hits there
//! with the reference's own code (`form_factor::tracer::Tracer::resolve`):
//! only the traversal, nearly all of a ray's cost, moves to the device. A
//! device without `cl_khr_fp64` cannot run it ([`DeviceTracer::new`] says
//! so); the stages then trace on the CPU and report that they did.
//!
//! Memory on the device: the BVH (`Node4` 128 B per four-wide node, `Node`
//! 32 B, `Tri` 48 B per triangle: 4.6 MB for Sponza's 66k triangles) and
//! one batch of rays (48 B in, 12 B out per ray: [`BATCH_RAYS`] rays are
//! 63 MB). `docs/memory.md` has the whole plan.

use crate::compute::{api, event_seconds, round_up, Access, Gpu};
use opencl3::kernel::{ExecuteKernel, Kernel};
use opencl3::memory::Buffer;
use opencl3::program::Program;
use opencl3::types::{cl_double, cl_uint, CL_BLOCKING};
use radiosity_core::bvh::{Bvh, Node, Tri};
use radiosity_core::bvh4::{Bvh4, Node4};
use radiosity_core::error::ClError;

/// The kernel's source.
pub const SOURCE: &str = include_str!("../kernels/trace.cl");

/// Rays traced per launch: about a million keeps a large GPU's every
/// core busy for several milliseconds (launch overhead negligible) while
/// the host's copies of a batch (origins, directions, hits: 60 MB) stay
/// small beside the form factors' own matrices.
pub const BATCH_RAYS: usize = 1 << 20;

/// Bytes on the device per ray of a batch: origin and direction (6 f64)
/// in, the leaf (u32) and `t` (f64) out.
pub const BYTES_PER_RAY: u64 = 6 * 8 + 4 + 8;

/// The BVH on the device, its kernel and one batch's buffers.
pub struct DeviceTracer<'g> {
    gpu: &'g Gpu,
    // Kept alive with the kernel built from it.
    _program: Program,
    kernel: Kernel,
    nodes4: Buffer<Node4>,
    nodes: Buffer<Node>,
    tris: Buffer<Tri>,
    origin: Buffer<cl_double>,
    dir: Buffer<cl_double>,
    leaf: Buffer<cl_uint>,
    t: Buffer<cl_double>,
    capacity: usize,
    local: usize,
    /// Device seconds of the launches so far (profiling events).
    pub seconds_kernels: f64,
    /// Rays traced so far.
    pub rays: u64,
}

impl<'g> DeviceTracer<'g> {
    /// Uploads `bvh` and its four-wide view and builds the kernel, with
    /// room for `capacity` rays a launch. Fails when the device has no
    /// `cl_khr_fp64` or the buffers do not fit.
    pub fn new(gpu: &'g Gpu, bvh: &Bvh, bvh4: &Bvh4, capacity: usize) -> Result<Self, ClError> {
        let info = gpu.info();
        if !info.fp64 {
            return Err(ClError::Build {
                name: "trace.cl".into(),
                device: info.name.clone(),
                log: "the device lacks cl_khr_fp64, which the ray kernel needs to match the \
                      CPU's f64 traversal"
                    .into(),
            });
        }
        let capacity = capacity.max(1);
        let bvh_bytes = (bvh4.nodes.len() * std::mem::size_of::<Node4>()
            + bvh.nodes.len() * std::mem::size_of::<Node>()
            + bvh.tris.len() * std::mem::size_of::<Tri>()) as u64;
        gpu.check_total(
            "the ray kernel",
            bvh_bytes + capacity as u64 * BYTES_PER_RAY,
        )?;
        // A four-wide node leaves at most three children on the stack per
        // level beside the one popped, four at the deepest (bvh4.rs's
        // STACK4 bound over the binary depth).
        let stack = 3 * (bvh.stats.max_depth as usize + 1) + 4;
        let program = gpu.build("trace.cl", SOURCE, &format!("-D STACK4={stack}"))?;
        let kernel = gpu.kernel(&program, "closest_hit")?;
        let local = gpu.local_size(&kernel, 64);
        Ok(Self {
            gpu,
            nodes4: gpu.upload("trace BVH4 nodes", &bvh4.nodes, Access::ReadOnly)?,
            nodes: gpu.upload("trace BVH nodes", &bvh.nodes, Access::ReadOnly)?,
            tris: gpu.upload("trace triangles", &bvh.tris, Access::ReadOnly)?,
            origin: gpu.buffer("trace origins", 3 * capacity, Access::ReadOnly)?,
            dir: gpu.buffer("trace directions", 3 * capacity, Access::ReadOnly)?,
            leaf: gpu.buffer("trace leaves", capacity, Access::WriteOnly)?,
            t: gpu.buffer("trace hit distances", capacity, Access::WriteOnly)?,
            _program: program,
            kernel,
            capacity,
            local,
            seconds_kernels: 0.0,
            rays: 0,
        })
    }

    /// The nearest hit of each segment `o + t d`, `t ∈ (0, 1]` (`o` and `d`
    /// three f64 per ray, in the BVH's shifted frame): the leaf-order
    /// triangle and `t`, as [`Bvh4::closest_hit`] answers.
    pub fn closest(&mut self, o: &[f64], d: &[f64]) -> Result<Vec<Option<(u32, f64)>>, ClError> {
        assert_eq!(o.len(), d.len(), "one direction per origin");
        let n = o.len() / 3;
        let mut out = Vec::with_capacity(n);
        for start in (0..n).step_by(self.capacity) {
            let m = (n - start).min(self.capacity);
            let (lo, hi) = (3 * start, 3 * (start + m));
            let queue = self.gpu.queue();
            // SAFETY: blocking writes of `3 m` f64 into buffers of `3 ·
            // capacity ≥ 3 m`, blocking reads of `m` elements from buffers
            // of `capacity ≥ m`; the kernel reads and writes only indices
            // below `m` (its `rays` argument).
            unsafe {
                queue
                    .enqueue_write_buffer(&mut self.origin, CL_BLOCKING, 0, &o[lo..hi], &[])
                    .map_err(|e| api("the ray kernel: writing origins", e))?;
                queue
                    .enqueue_write_buffer(&mut self.dir, CL_BLOCKING, 0, &d[lo..hi], &[])
                    .map_err(|e| api("the ray kernel: writing directions", e))?;
                let event = ExecuteKernel::new(&self.kernel)
                    .set_arg(&self.nodes4)
                    .set_arg(&self.nodes)
                    .set_arg(&self.tris)
                    .set_arg(&self.origin)
                    .set_arg(&self.dir)
                    .set_arg(&self.leaf)
                    .set_arg(&self.t)
                    .set_arg(&(m as cl_uint))
                    .set_global_work_size(round_up(m, self.local))
                    .set_local_work_size(self.local)
                    .enqueue_nd_range(queue)
                    .map_err(|e| api("the ray kernel: launching closest_hit", e))?;
                event
                    .wait()
                    .map_err(|e| api("the ray kernel: running closest_hit", e))?;
                self.seconds_kernels += event_seconds(&event)?;
                let mut leaf = vec![0u32; m];
                let mut t = vec![0.0f64; m];
                queue
                    .enqueue_read_buffer(&self.leaf, CL_BLOCKING, 0, &mut leaf, &[])
                    .map_err(|e| api("the ray kernel: reading leaves", e))?;
                queue
                    .enqueue_read_buffer(&self.t, CL_BLOCKING, 0, &mut t, &[])
                    .map_err(|e| api("the ray kernel: reading hit distances", e))?;
                out.extend(
                    leaf.iter()
                        .zip(&t)
                        .map(|(&l, &t)| (l != u32::MAX).then_some((l, t))),
                );
            }
            self.rays += m as u64;
        }
        Ok(out)
    }
}

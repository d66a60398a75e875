//! The near-field correction on the GPU (`crates/gl/glsl/near_field.comp`): the
//! bake's near-neighbour weights ([`radiosity_runtime::near_field`], its CPU
//! reference) applied to `D` at the lit points of the direct pass, in two
//! dispatches around the gather: its input `B0 + δ + ρ ∘ c` before it (into
//! a buffer of its own, so `B0` stays what the direct pass made), `H += c`
//! after.
//! A bake without the correction compiles nothing and dispatches nothing.

use super::{bytes_of, compile_compute, storage_buffer, GlError};
use glow::HasContext;
use radiosity_bakefile::codec::TILE;
use radiosity_bakefile::surface::SAMPLES_PER_PATCH;
use radiosity_runtime::near_field::NearFieldWeights;

pub const SOURCE: &str = include_str!("../glsl/near_field.comp");

/// The pass, when the bake has a correction.
pub struct GlNearField {
    program: glow::Program,
    /// Starts, link patches, link weights, `c`, the gather's input, each
    /// patch's own weights for `δ`, the links' weights at the receiver's
    /// points, `H`'s deviation at each patch's points (bindings 0, 1, 2, 5,
    /// 9, 10, 11, 12).
    buffers: [glow::Buffer; 8],
    /// Whether the bake stores the links' counts by the receiver's cell
    /// (stage 2 runs).
    receiver: bool,
    n: usize,
    m: usize,
    /// Each patch's sky factors at its lit points
    /// ([`NearFieldWeights::sky`]; empty when the bake has none).
    sky: Vec<[f32; SAMPLES_PER_PATCH]>,
}

/// The buffers the pass reads (and `H`, `active`, writes) that other
/// passes own.
pub struct NearFieldInputs {
    pub d_points: glow::Buffer,
    pub albedo: glow::Buffer,
    pub b0: glow::Buffer,
    pub active: glow::Buffer,
    pub h: glow::Buffer,
}

impl GlNearField {
    /// Uploads `w`'s links; `None` when there are none.
    pub fn new(gl: &glow::Context, w: &NearFieldWeights) -> Result<Option<GlNearField>, GlError> {
        if w.is_empty() {
            return Ok(None);
        }
        let program = compile_compute(
            gl,
            "near_field.comp",
            &[SOURCE],
            &[("SAMPLES_PER_PATCH", SAMPLES_PER_PATCH), ("TILE", TILE)],
        )?;
        let n = w.starts.len() - 1;
        let weights: Vec<f32> = w.weights.iter().flatten().copied().collect();
        // Zeros for a bake without far weights: δ = 0.
        let own: Vec<f32> = if w.own.is_empty() {
            vec![0.0; SAMPLES_PER_PATCH * n]
        } else {
            w.own.iter().flatten().copied().collect()
        };
        let buffers = [
            storage_buffer(gl, bytes_of(&w.starts), glow::STATIC_DRAW)?,
            storage_buffer(gl, bytes_of(&w.patch), glow::STATIC_DRAW)?,
            storage_buffer(gl, bytes_of(&weights), glow::STATIC_DRAW)?,
            storage_buffer(gl, &vec![0u8; 12 * n], glow::DYNAMIC_COPY)?,
            storage_buffer(gl, &vec![0u8; 12 * n], glow::DYNAMIC_COPY)?,
            storage_buffer(gl, bytes_of(&own), glow::STATIC_DRAW)?,
            storage_buffer(
                gl,
                bytes_of(&w.receiver.iter().flatten().copied().collect::<Vec<f32>>()),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(
                gl,
                &vec![0u8; 12 * n * SAMPLES_PER_PATCH],
                glow::DYNAMIC_COPY,
            )?,
        ];
        super::check(gl, "uploading the near-field correction")?;
        Ok(Some(GlNearField {
            program,
            buffers,
            receiver: !w.receiver.is_empty(),
            n,
            m: w.m,
            sky: w.sky.clone(),
        }))
    }

    /// The sky's irradiance at the lit points (3 × n × m, the direct
    /// pass's `D` at the points' layout) from `D_sky` per patch, for the
    /// correction to see the sky as the CPU does
    /// ([`NearFieldWeights::sky_points`]); `None` when the bake stores no
    /// open sky per cell.
    pub fn sky_points(&self, d: &[Vec<f32>; 3]) -> Option<Vec<f32>> {
        if self.sky.is_empty() {
            return None;
        }
        let p = radiosity_runtime::near_field::sky_points(&self.sky, self.m, d);
        Some(p.into_iter().flatten().collect())
    }

    /// Whether stage 2 (`H`'s deviation at the receivers' points) runs.
    pub fn has_receiver(&self) -> bool {
        self.receiver
    }

    /// `H`'s deviation in each patch's face cells (3 × n × 16, channel-major;
    /// [`radiosity_runtime::Runtime::h_points`]'s layout).
    pub fn h_points_buffer(&self) -> glow::Buffer {
        self.buffers[7]
    }

    /// The correction `c` of the last frame (3 n, channel-major).
    pub fn c_buffer(&self) -> glow::Buffer {
        self.buffers[3]
    }

    /// What the gather reads: `B0 + δ + ρ ∘ c` (3 n, channel-major).
    pub fn gather_input(&self) -> glow::Buffer {
        self.buffers[4]
    }

    /// Points lit per patch the weights were made for.
    pub fn samples(&self) -> usize {
        self.m
    }

    /// Dispatches stage 0 (`c`, the input `B0 + δ + ρ ∘ c`, tile flags),
    /// stage 1 (`H += c`) or stage 2 (`H`'s deviation at the receivers'
    /// points, from `B0` and the corrected `H`), with a barrier before it.
    pub fn dispatch(&self, gl: &glow::Context, stage: u32, io: &NearFieldInputs) {
        // SAFETY: binds, uniforms and a dispatch on the current context;
        // buffers sized for `n` patches and `m` points in `new` and by
        // their owners.
        unsafe {
            gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT);
            gl.use_program(Some(self.program));
            let b = glow::SHADER_STORAGE_BUFFER;
            gl.bind_buffer_base(b, 0, Some(self.buffers[0]));
            gl.bind_buffer_base(b, 1, Some(self.buffers[1]));
            gl.bind_buffer_base(b, 2, Some(self.buffers[2]));
            gl.bind_buffer_base(b, 3, Some(io.d_points));
            gl.bind_buffer_base(b, 4, Some(io.albedo));
            gl.bind_buffer_base(b, 5, Some(self.buffers[3]));
            gl.bind_buffer_base(b, 6, Some(io.b0));
            gl.bind_buffer_base(b, 7, Some(io.active));
            gl.bind_buffer_base(b, 8, Some(io.h));
            gl.bind_buffer_base(b, 9, Some(self.buffers[4]));
            gl.bind_buffer_base(b, 10, Some(self.buffers[5]));
            gl.bind_buffer_base(b, 11, Some(self.buffers[6]));
            gl.bind_buffer_base(b, 12, Some(self.buffers[7]));
            let loc = |name: &str| gl.get_uniform_location(self.program, name);
            gl.uniform_1_u32(loc("n").as_ref(), self.n as u32);
            gl.uniform_1_u32(loc("samples").as_ref(), self.m as u32);
            gl.uniform_1_u32(loc("stage").as_ref(), stage);
            gl.dispatch_compute(self.n.div_ceil(64).max(1) as u32, 1, 1);
        }
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            for b in self.buffers {
                gl.delete_buffer(b);
            }
        }
    }
}

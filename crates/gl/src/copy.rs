//! A buffer copy on the GPU (`crates/gl/glsl/copy.comp`): the memory roof that
//! `bench frame` measures in the same run as the gather and reports the
//! gather's effective bandwidth against, as the CPU side is measured
//! against a STREAM-like triad. Its CPU reference is the identity
//! (tests/gl_classic.rs checks the copy word for word).

use super::{bytes_of, compile_compute, gpu_seconds, storage_buffer, GlError};
use glow::HasContext;

/// The shader's source (without the `#version` line).
pub const SOURCE: &str = include_str!("../glsl/copy.comp");

/// Work-groups of 256 invocations a copy dispatches (each invocation
/// strides over the buffer: enough to fill any GPU, few enough to stay
/// within every GL's dispatch limit).
const GROUPS: u32 = 4096;

/// Two buffers of the same size and the copy between them.
pub struct GlCopy {
    program: glow::Program,
    src: glow::Buffer,
    dst: glow::Buffer,
    /// 16-byte words copied.
    words: usize,
}

impl GlCopy {
    /// Two buffers of `bytes` bytes (rounded up to 16), the source filled
    /// with a counting pattern (word `k` holds `k`).
    pub fn new(gl: &glow::Context, bytes: usize) -> Result<GlCopy, GlError> {
        let words = bytes.div_ceil(16).max(1);
        let pattern: Vec<u32> = (0..4 * words as u32).collect();
        let program = compile_compute(gl, "copy.comp", &[SOURCE], &[])?;
        let src = storage_buffer(gl, bytes_of(&pattern), glow::STATIC_DRAW)?;
        let dst = storage_buffer(gl, &vec![0u8; 16 * words], glow::DYNAMIC_COPY)?;
        // SAFETY: a uniform of this context's program.
        unsafe {
            gl.use_program(Some(program));
            let loc = gl.get_uniform_location(program, "words");
            gl.uniform_1_u32(loc.as_ref(), words as u32);
            gl.use_program(None);
        }
        let copy = GlCopy {
            program,
            src,
            dst,
            words,
        };
        if let Err(e) = super::check(gl, "allocating the copy's buffers") {
            copy.delete(gl);
            return Err(e);
        }
        Ok(copy)
    }

    /// Bytes one copy reads and writes together.
    pub fn bytes_moved(&self) -> u64 {
        32 * self.words as u64
    }

    /// Dispatches one copy.
    pub fn run(&self, gl: &glow::Context) {
        // SAFETY: binds and a dispatch on the current context.
        unsafe {
            gl.use_program(Some(self.program));
            gl.bind_buffer_base(glow::SHADER_STORAGE_BUFFER, 0, Some(self.src));
            gl.bind_buffer_base(glow::SHADER_STORAGE_BUFFER, 1, Some(self.dst));
            gl.dispatch_compute(GROUPS, 1, 1);
        }
    }

    /// Bytes read and written per second by the fastest of `repeat`
    /// copies, timed on the GPU.
    pub fn bandwidth(&self, gl: &glow::Context, repeat: usize) -> Result<f64, GlError> {
        let t = gpu_seconds(gl, repeat, || self.run(gl))?;
        Ok(self.bytes_moved() as f64 / t.max(1e-12))
    }

    /// The destination read back, as u32 words (blocking).
    pub fn read(&self, gl: &glow::Context) -> Vec<u32> {
        super::read_floats(gl, self.dst, 4 * self.words)
            .into_iter()
            .map(f32::to_bits)
            .collect()
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_buffer(self.src);
            gl.delete_buffer(self.dst);
        }
    }
}

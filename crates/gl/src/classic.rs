//! Classic radiosity on the GPU (`crates/gl/glsl/classic.comp`): the baseline the
//! thesis's compressed gather is measured against (docs/design.md section 3),
//! on the same device. A pass reads the dense f32 form-factor matrix `F`
//! (matrix order, as the run time's patches) once and updates the three
//! channels: `y_c = F x_c`, `H += y`, `x = ρ ∘ y`; k passes are k bounces,
//! and passes repeated until the compressed gather's error is reached are
//! the Jacobi iteration of the infinite-bounce limit. Its CPU reference is
//! `bench::frame::classic` (tests/gl_classic.rs).

use super::{bytes_of, compile_compute, storage_buffer, GlError};
use glow::HasContext;

/// The shader's source (without the `#version` line).
pub const SOURCE: &str = include_str!("../glsl/classic.comp");

/// Rows a work-group takes (`ROWS` in the shader).
const ROWS_PER_GROUP: usize = 8;

/// `F` and the albedos on the GPU, with the buffers of a product.
pub struct GlClassic {
    program: glow::Program,
    f: glow::Buffer,
    albedo: glow::Buffer,
    /// The two inputs (ping-pong) and `H`.
    x: [glow::Buffer; 2],
    h: glow::Buffer,
    n: usize,
    /// Floats a row of `F` on the GPU: `n` rounded up to 4.
    stride: usize,
}

impl GlClassic {
    /// Uploads `f` (n × n, row-major, f32) and the patches' albedos; the
    /// context must be current. `F` takes `4 n²` bytes (rows padded to a
    /// multiple of 4 floats): a GL that cannot hold it in one storage
    /// block says so.
    pub fn new(
        gl: &glow::Context,
        f: &[f32],
        n: usize,
        albedo: &[[f32; 3]],
    ) -> Result<GlClassic, GlError> {
        assert_eq!(f.len(), n * n, "F must be n × n");
        assert_eq!(albedo.len(), n, "one albedo per patch");
        let stride = n.div_ceil(4) * 4;
        let bytes = 4 * stride as u64 * n as u64;
        // SAFETY: a query on the current context.
        let max_block = unsafe { gl.get_parameter_i64(glow::MAX_SHADER_STORAGE_BLOCK_SIZE) };
        if bytes as i64 > max_block {
            return Err(GlError::Unsupported(format!(
                "F of {n} patches takes {bytes} bytes; this GL allows a storage block of {max_block}"
            )));
        }
        let mut padded = vec![0.0f32; stride * n];
        for (i, row) in f.chunks_exact(n.max(1)).enumerate() {
            padded[i * stride..i * stride + n].copy_from_slice(row);
        }
        let rho: Vec<f32> = albedo
            .iter()
            .flat_map(|a| [a[0], a[1], a[2], 0.0])
            .collect();
        let program = compile_compute(gl, "classic.comp", &[SOURCE], &[])?;
        let zeros = vec![0u8; 16 * stride.max(1)];
        let classic = GlClassic {
            program,
            f: storage_buffer(gl, bytes_of(&padded), glow::STATIC_DRAW)?,
            albedo: storage_buffer(gl, bytes_of(&rho), glow::STATIC_DRAW)?,
            x: [
                storage_buffer(gl, &zeros, glow::DYNAMIC_COPY)?,
                storage_buffer(gl, &zeros, glow::DYNAMIC_COPY)?,
            ],
            h: storage_buffer(gl, &zeros, glow::DYNAMIC_COPY)?,
            n,
            stride,
        };
        // SAFETY: uniforms of this context's program.
        unsafe {
            gl.use_program(Some(program));
            let loc = |name: &str| gl.get_uniform_location(program, name);
            gl.uniform_1_u32(loc("n").as_ref(), n as u32);
            gl.uniform_1_u32(loc("stride").as_ref(), stride as u32);
            gl.use_program(None);
        }
        if let Err(e) = super::check(gl, "uploading F") {
            classic.delete(gl);
            return Err(e);
        }
        Ok(classic)
    }

    /// Bytes of `F` one pass reads.
    pub fn bytes_per_pass(&self) -> u64 {
        4 * self.stride as u64 * self.n as u64
    }

    /// Uploads `b0` (three channels of `n`) as the first pass's input and
    /// clears `H`.
    pub fn set_input(&self, gl: &glow::Context, b0: &[Vec<f32>; 3]) {
        let mut x = vec![0.0f32; 4 * self.stride];
        for c in 0..3 {
            assert_eq!(b0[c].len(), self.n, "B0 must have one value per patch");
            for (j, &v) in b0[c].iter().enumerate() {
                x[4 * j + c] = v;
            }
        }
        let zeros = vec![0.0f32; 4 * self.stride];
        // SAFETY: uploads into buffers of 16 stride bytes.
        unsafe {
            for (b, data) in [(self.x[0], &x), (self.x[1], &zeros), (self.h, &zeros)] {
                gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(b));
                gl.buffer_sub_data_u8_slice(glow::SHADER_STORAGE_BUFFER, 0, bytes_of(data));
            }
            gl.memory_barrier(glow::BUFFER_UPDATE_BARRIER_BIT);
        }
    }

    /// Dispatches `k` passes on the input [`GlClassic::set_input`] gave
    /// (each pass's output is the next one's input).
    pub fn run(&self, gl: &glow::Context, k: usize) {
        let groups = self.n.div_ceil(ROWS_PER_GROUP).max(1) as u32;
        // SAFETY: binds and dispatches on the current context.
        unsafe {
            gl.use_program(Some(self.program));
            let b = glow::SHADER_STORAGE_BUFFER;
            gl.bind_buffer_base(b, 0, Some(self.f));
            gl.bind_buffer_base(b, 3, Some(self.h));
            gl.bind_buffer_base(b, 4, Some(self.albedo));
            for pass in 0..k {
                gl.bind_buffer_base(b, 1, Some(self.x[pass % 2]));
                gl.bind_buffer_base(b, 2, Some(self.x[(pass + 1) % 2]));
                gl.dispatch_compute(groups, 1, 1);
                gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT);
            }
        }
    }

    /// `H` read back (blocking), three channels of `n`.
    pub fn read_h(&self, gl: &glow::Context) -> Result<[Vec<f32>; 3], GlError> {
        let v = super::read_floats(gl, self.h, 4 * self.n);
        super::check(gl, "classic radiosity")?;
        Ok(std::array::from_fn(|c| {
            (0..self.n).map(|j| v[4 * j + c]).collect()
        }))
    }

    /// `k` bounces from `b0`: uploads, runs and reads back.
    pub fn bounces(
        &self,
        gl: &glow::Context,
        b0: &[Vec<f32>; 3],
        k: usize,
    ) -> Result<[Vec<f32>; 3], GlError> {
        self.set_input(gl, b0);
        self.run(gl, k);
        self.read_h(gl)
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            for b in [self.f, self.albedo, self.x[0], self.x[1], self.h] {
                gl.delete_buffer(b);
            }
        }
    }
}

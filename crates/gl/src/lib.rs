//! The OpenGL renderer (docs/design.md run time on the GPU), one file per pass
//! paired with its shader in `crates/gl/glsl/`, each tested against the CPU run time
//! ([`radiosity_runtime`]) that defines what it computes. Shaders are real
//! files embedded with `include_str!`; the `#version` line (and compile-time
//! defines) are added in one place, [`compile_compute`]. The frame
//! ([`renderer`]): shadow maps ([`shadow`]), direct light on patches through
//! the CPU's shadow rays ([`direct`]), the near-field correction
//! ([`near_field`]), the compressed gather decoded in the shader
//! ([`gather`]), shading ([`shade`]) and tone mapping ([`tonemap`]); the
//! benchmarks' GPU baselines ([`classic`], [`copy`]); a headless context
//! ([`context`]).

// NaN-aware tests: `!(x > 0.0)` is true for NaN, which is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod classic;
pub mod context;
pub mod copy;
pub mod direct;
pub mod gather;
pub mod light;
pub mod near_field;
pub mod objects;
pub mod probes;
pub mod renderer;
pub mod scene;
pub mod shade;
pub mod shadow;
pub mod sky;
pub mod surface;
pub mod tonemap;

use glow::HasContext;

/// The GLSL version every shader is compiled with (GL 4.5 core: compute
/// shaders, storage buffers).
pub const GLSL_VERSION: &str = "#version 450 core";

/// Errors of the GL renderer.
#[derive(Debug, thiserror::Error)]
pub enum GlError {
    /// No device or driver gave a context (install Mesa EGL: scripts/setup).
    #[error("no OpenGL device: {0}")]
    NoDevice(String),
    /// A device was found but no context could be made on it.
    #[error("OpenGL context: {0}")]
    Context(String),
    /// A shader that does not compile or link, with the driver's log.
    #[error("shader {name}: {log}")]
    Shader { name: String, log: String },
    /// Data this renderer does not handle (yet), named.
    #[error("{0}")]
    Unsupported(String),
    /// A GL call that failed.
    #[error("OpenGL: {0}")]
    Call(String),
    /// The GPU (or llvmpipe's host memory) could not hold `what`, `bytes`
    /// bytes: a smaller resolution or fewer lights may fit.
    #[error("OpenGL: out of memory for {what} ({:.2} GiB)", *bytes as f64 / (1u64 << 30) as f64)]
    OutOfMemory { what: String, bytes: u64 },
    /// `what` would take `bytes` bytes, more than the `budget` the caller
    /// set for it: a smaller resolution, fewer lights or a larger budget
    /// fits.
    #[error(
        "{what} would take {:.2} MiB, over the budget of {:.2} MiB",
        *bytes as f64 / (1u64 << 20) as f64,
        *budget as f64 / (1u64 << 20) as f64
    )]
    OverBudget {
        what: String,
        bytes: u64,
        budget: u64,
    },
}

/// The sources concatenated after the version line and `#define NAME
/// value` lines: shared GLSL files (`light.glsl`, `surface.glsl`) come
/// before the shader that uses them (GLSL core has no `#include`).
pub fn with_header(sources: &[&str], defines: &[(&str, usize)]) -> String {
    let mut s = format!("{GLSL_VERSION}\n");
    for (name, value) in defines {
        s += &format!("#define {name} {value}\n");
    }
    for src in sources {
        s += src;
        s += "\n";
    }
    s
}

/// One stage of a program: its kind (`glow::VERTEX_SHADER`, ...), the
/// file name for messages, and its sources in order.
pub struct Stage<'a> {
    pub kind: u32,
    pub name: &'a str,
    pub sources: &'a [&'a str],
}

/// Compiles and links a compute shader (`name` for messages).
pub fn compile_compute(
    gl: &glow::Context,
    name: &str,
    sources: &[&str],
    defines: &[(&str, usize)],
) -> Result<glow::Program, GlError> {
    compile_program(
        gl,
        &[Stage {
            kind: glow::COMPUTE_SHADER,
            name,
            sources,
        }],
        defines,
    )
}

/// Compiles the stages and links them into one program. A stage that does
/// not compile names its file and gives the driver's log; a link error
/// names every file.
pub fn compile_program(
    gl: &glow::Context,
    stages: &[Stage],
    defines: &[(&str, usize)],
) -> Result<glow::Program, GlError> {
    let all_names = stages
        .iter()
        .map(|s| s.name)
        .collect::<Vec<_>>()
        .join(" + ");
    // SAFETY: object creation, compilation and linking on the current
    // context; objects are deleted on every path.
    unsafe {
        let mut shaders = Vec::new();
        let cleanup = |shaders: &[glow::Shader]| {
            for &sh in shaders {
                gl.delete_shader(sh);
            }
        };
        for stage in stages {
            let err = |log: String| GlError::Shader {
                name: stage.name.to_string(),
                log,
            };
            let shader = match gl.create_shader(stage.kind) {
                Ok(sh) => sh,
                Err(e) => {
                    cleanup(&shaders);
                    return Err(err(e));
                }
            };
            gl.shader_source(shader, &with_header(stage.sources, defines));
            gl.compile_shader(shader);
            if !gl.get_shader_compile_status(shader) {
                let log = gl.get_shader_info_log(shader);
                gl.delete_shader(shader);
                cleanup(&shaders);
                return Err(err(log));
            }
            shaders.push(shader);
        }
        let link_error = |log: String| GlError::Shader {
            name: all_names.clone(),
            log,
        };
        let program = match gl.create_program() {
            Ok(p) => p,
            Err(e) => {
                cleanup(&shaders);
                return Err(link_error(e));
            }
        };
        for &sh in &shaders {
            gl.attach_shader(program, sh);
        }
        gl.link_program(program);
        for &sh in &shaders {
            gl.detach_shader(program, sh);
        }
        cleanup(&shaders);
        if !gl.get_program_link_status(program) {
            let log = gl.get_program_info_log(program);
            gl.delete_program(program);
            return Err(link_error(log));
        }
        Ok(program)
    }
}

/// `v` as bytes (plain 4-byte values: no padding).
pub(crate) fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // SAFETY: the callers pass u32, i32, f32 and f64 values, arrays of
    // them, and `repr(C)` structs of 4-byte fields (core::bvh's Node and
    // Tri), which have no padding or invalid bit patterns as bytes.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast(), std::mem::size_of_val(v)) }
}

/// A new storage buffer holding `data` (at least 4 bytes: an empty buffer
/// cannot be bound).
pub(crate) fn storage_buffer(
    gl: &glow::Context,
    data: &[u8],
    usage: u32,
) -> Result<glow::Buffer, GlError> {
    // SAFETY: object creation and an upload of `data` on the current
    // context.
    unsafe {
        let b = gl.create_buffer().map_err(GlError::Call)?;
        fill_buffer(gl, b, data, usage);
        Ok(b)
    }
}

/// Replaces the contents of storage buffer `b` with `data` (at least 4
/// bytes).
pub(crate) fn fill_buffer(gl: &glow::Context, b: glow::Buffer, data: &[u8], usage: u32) {
    let data = if data.is_empty() { &[0u8; 4][..] } else { data };
    // SAFETY: an upload of `data` into a buffer of this context.
    unsafe {
        gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(b));
        gl.buffer_data_u8_slice(glow::SHADER_STORAGE_BUFFER, data, usage);
    }
}

/// The first `count` f32 values of storage buffer `b` (a blocking read:
/// for tests and one-off renders, not for frames).
pub fn read_floats(gl: &glow::Context, b: glow::Buffer, count: usize) -> Vec<f32> {
    let mut out = vec![0u8; 4 * count];
    // SAFETY: a barrier and a read of `4 count` bytes, within the buffer's
    // size by the caller.
    unsafe {
        gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT | glow::BUFFER_UPDATE_BARRIER_BIT);
        gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(b));
        gl.get_buffer_sub_data(glow::SHADER_STORAGE_BUFFER, 0, &mut out);
    }
    out.chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// `Err` naming `what` when GL reports an error.
pub(crate) fn check(gl: &glow::Context, what: &str) -> Result<(), GlError> {
    // SAFETY: an error query on the current context.
    let code = unsafe { gl.get_error() };
    if code == glow::NO_ERROR {
        Ok(())
    } else {
        Err(GlError::Call(format!("{what}: GL error 0x{code:x}")))
    }
}

/// The GPU time of `f`'s commands, the fastest of `repeat` runs (seconds):
/// a timestamp query before and after each run, read when the GPU is done
/// (blocking: for benchmarks, not frames; the renderer's own timers never
/// wait). `glQueryCounter` timestamps are right on every driver tried,
/// Mesa's llvmpipe included.
pub fn gpu_seconds(gl: &glow::Context, repeat: usize, mut f: impl FnMut()) -> Result<f64, GlError> {
    let mut best = f64::INFINITY;
    // SAFETY: queries created, issued, read and deleted on the current
    // context; the u64 results are written to locals (no query buffer is
    // bound).
    unsafe {
        let q0 = gl.create_query().map_err(GlError::Call)?;
        let q1 = match gl.create_query() {
            Ok(q) => q,
            Err(e) => {
                gl.delete_query(q0);
                return Err(GlError::Call(e));
            }
        };
        for _ in 0..repeat.max(1) {
            gl.query_counter(q0, glow::TIMESTAMP);
            f();
            gl.query_counter(q1, glow::TIMESTAMP);
            best = best.min(elapsed_ns(gl, q0, q1) as f64 * 1e-9);
        }
        gl.delete_query(q0);
        gl.delete_query(q1);
        check(gl, "timing on the GPU")?;
    }
    Ok(best)
}

/// Nanoseconds between two issued timestamp queries (blocking until both
/// results are there; the u64 results are written to locals, no query
/// buffer being bound).
pub(crate) fn elapsed_ns(gl: &glow::Context, q0: glow::Query, q1: glow::Query) -> u64 {
    let (mut t0, mut t1) = (0u64, 0u64);
    // SAFETY: result queries of timestamps issued on the current context,
    // written to the two locals.
    unsafe {
        gl.get_query_parameter_u64_with_offset(
            q0,
            glow::QUERY_RESULT,
            &mut t0 as *mut u64 as usize,
        );
        gl.get_query_parameter_u64_with_offset(
            q1,
            glow::QUERY_RESULT,
            &mut t1 as *mut u64 as usize,
        );
    }
    t1.saturating_sub(t0)
}

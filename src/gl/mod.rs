//! The OpenGL renderer (DESIGN.md run time on the GPU), one file per pass
//! paired with its shader in `glsl/`, each tested against the CPU run time
//! ([`crate::runtime`]) that defines what it computes. Shaders are real
//! files embedded with `include_str!`; the `#version` line (and compile-time
//! defines) are added in one place, [`compile_compute`]. So far: a headless
//! context ([`context`]) and the compressed gather ([`gather`]).

pub mod context;
pub mod gather;

use glow::HasContext;

/// The GLSL version every shader is compiled with (GL 4.5 core: compute
/// shaders, storage buffers, `texelFetch` on compressed textures).
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
}

/// `source` with the version line and `#define NAME value` lines prepended.
pub fn with_header(source: &str, defines: &[(&str, usize)]) -> String {
    let mut s = format!("{GLSL_VERSION}\n");
    for (name, value) in defines {
        s += &format!("#define {name} {value}\n");
    }
    s + source
}

/// Compiles and links a compute shader (`name` for messages).
pub fn compile_compute(
    gl: &glow::Context,
    name: &str,
    source: &str,
    defines: &[(&str, usize)],
) -> Result<glow::Program, GlError> {
    let full = with_header(source, defines);
    let shader_error = |log: String| GlError::Shader {
        name: name.to_string(),
        log,
    };
    // SAFETY: object creation, compilation and linking on the current
    // context; objects are deleted on every path.
    unsafe {
        let shader = gl
            .create_shader(glow::COMPUTE_SHADER)
            .map_err(shader_error)?;
        gl.shader_source(shader, &full);
        gl.compile_shader(shader);
        if !gl.get_shader_compile_status(shader) {
            let log = gl.get_shader_info_log(shader);
            gl.delete_shader(shader);
            return Err(shader_error(log));
        }
        let program = gl.create_program().map_err(shader_error)?;
        gl.attach_shader(program, shader);
        gl.link_program(program);
        gl.detach_shader(program, shader);
        gl.delete_shader(shader);
        if !gl.get_program_link_status(program) {
            let log = gl.get_program_info_log(program);
            gl.delete_program(program);
            return Err(shader_error(log));
        }
        Ok(program)
    }
}

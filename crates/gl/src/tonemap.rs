//! Tone mapping for display (`crates/gl/glsl/fullscreen.vert`, `crates/gl/glsl/tonemap.frag`):
//! the shading pass's radiance texture through the exposure, the filmic
//! curve and the sRGB OETF into an 8-bit target (the window, or a
//! framebuffer in the tests). Its CPU reference is
//! [`radiosity_runtime::tonemap::to_srgb8`]; tests/gl_render.rs compares the
//! two within one 8-bit step (f32 `pow` and the rounding of the target).

use super::{compile_program, GlError, Stage};
use glow::HasContext;

pub const VERTEX: &str = include_str!("../glsl/fullscreen.vert");
pub const FRAGMENT: &str = include_str!("../glsl/tonemap.frag");

/// The pass.
pub struct Tonemap {
    program: glow::Program,
    vao: glow::VertexArray,
}

/// A full-screen pass's program: `fullscreen.vert` (one triangle over the
/// viewport) with the fragment shader `source` (`name` for messages).
pub(crate) fn fullscreen_program(
    gl: &glow::Context,
    name: &str,
    source: &str,
) -> Result<glow::Program, GlError> {
    compile_program(
        gl,
        &[
            Stage {
                kind: glow::VERTEX_SHADER,
                name: "fullscreen.vert",
                sources: &[VERTEX],
            },
            Stage {
                kind: glow::FRAGMENT_SHADER,
                name,
                sources: &[source],
            },
        ],
        &[],
    )
}

impl Tonemap {
    pub fn new(gl: &glow::Context) -> Result<Tonemap, GlError> {
        let program = fullscreen_program(gl, "tonemap.frag", FRAGMENT)?;
        // SAFETY: object creation on the current context (core profile
        // draws need a vertex array even without attributes).
        let vao = unsafe { gl.create_vertex_array() }.map_err(GlError::Call)?;
        Ok(Tonemap { program, vao })
    }

    /// Draws `radiance` (a texture of `size`) with `exposure` into the
    /// bound draw framebuffer `target` (`None`: the window's).
    pub fn draw(
        &self,
        gl: &glow::Context,
        radiance: glow::Texture,
        size: (usize, usize),
        exposure: f32,
        target: Option<glow::Framebuffer>,
    ) {
        // SAFETY: state, binds and one draw on the current context.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, target);
            gl.viewport(0, 0, size.0 as i32, size.1 as i32);
            gl.disable(glow::DEPTH_TEST);
            gl.disable(glow::FRAMEBUFFER_SRGB);
            gl.use_program(Some(self.program));
            gl.active_texture(glow::TEXTURE0);
            gl.bind_texture(glow::TEXTURE_2D, Some(radiance));
            let loc = |name: &str| gl.get_uniform_location(self.program, name);
            gl.uniform_1_i32(loc("radiance").as_ref(), 0);
            gl.uniform_1_f32(loc("exposure").as_ref(), exposure);
            gl.bind_vertex_array(Some(self.vao));
            gl.draw_arrays(glow::TRIANGLES, 0, 3);
            gl.bind_vertex_array(None);
        }
    }

    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_vertex_array(self.vao);
        }
    }
}

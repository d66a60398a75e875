//! Moving objects on the GPU (`crates/gl/glsl/object.vert`,
//! `crates/gl/glsl/object.frag`): their placed triangles
//! (`radiosity_core::objects`), drawn into the shading pass's target after
//! the scene with the lights' direct light through the shadow maps (which
//! they are drawn into as well, so they cast shadows) and the probes'
//! irradiance (`probe_lookup.glsl`). The CPU reference of the lookup is
//! `radiosity_runtime::probes::Lookup` (tests/gl_probes.rs).

use super::direct::{
    BVH_NODE_BINDING, BVH_TRI_BINDING, LIGHT, LIGHT_BINDING, RAY_BINDING, SHADOW_RAY, VIEW_BINDING,
};
use super::probes::{GlProbes, LOOKUP, SH_BINDING, STATE_BINDING};
use super::{bytes_of, compile_program, GlError, Stage};
use glow::HasContext;
use radiosity_core::objects::Vertex;
use radiosity_runtime::render::View;

const VERTEX: &str = include_str!("../glsl/object.vert");
const FRAGMENT: &str = include_str!("../glsl/object.frag");

/// The objects' geometry and program.
pub struct GlObjects {
    pub program: glow::Program,
    vao: glow::VertexArray,
    vbo: glow::Buffer,
    vertices: usize,
}

impl GlObjects {
    pub fn new(gl: &glow::Context) -> Result<GlObjects, GlError> {
        let program = compile_program(
            gl,
            &[
                Stage {
                    kind: glow::VERTEX_SHADER,
                    name: "object.vert",
                    sources: &[VERTEX],
                },
                Stage {
                    kind: glow::FRAGMENT_SHADER,
                    name: "object.frag",
                    sources: &[SHADOW_RAY, LIGHT, LOOKUP, FRAGMENT],
                },
            ],
            &[
                ("LIGHT_BINDING", LIGHT_BINDING),
                ("VIEW_BINDING", VIEW_BINDING),
                ("BVH_NODE_BINDING", BVH_NODE_BINDING),
                ("BVH_TRI_BINDING", BVH_TRI_BINDING),
                ("RAY_BINDING", RAY_BINDING),
                ("PROBE_SH_BINDING", SH_BINDING),
                ("PROBE_STATE_BINDING", STATE_BINDING),
            ],
        )?;
        // SAFETY: object creation and attribute setup on the current
        // context.
        let (vao, vbo) = unsafe {
            let vao = gl.create_vertex_array().map_err(GlError::Call)?;
            let vbo = gl.create_buffer().map_err(GlError::Call)?;
            gl.bind_vertex_array(Some(vao));
            gl.bind_buffer(glow::ARRAY_BUFFER, Some(vbo));
            let stride = std::mem::size_of::<Vertex>() as i32;
            for (k, offset) in [0, 12, 24].into_iter().enumerate() {
                gl.enable_vertex_attrib_array(k as u32);
                gl.vertex_attrib_pointer_f32(k as u32, 3, glow::FLOAT, false, stride, offset);
            }
            gl.bind_vertex_array(None);
            (vao, vbo)
        };
        Ok(GlObjects {
            program,
            vao,
            vbo,
            vertices: 0,
        })
    }

    /// The placed triangles of every object (three vertices a triangle).
    pub fn set(&mut self, gl: &glow::Context, vertices: &[Vertex]) {
        // SAFETY: a buffer upload on the current context.
        unsafe {
            gl.bind_buffer(glow::ARRAY_BUFFER, Some(self.vbo));
            gl.buffer_data_u8_slice(glow::ARRAY_BUFFER, bytes_of(vertices), glow::DYNAMIC_DRAW);
            gl.bind_buffer(glow::ARRAY_BUFFER, None);
        }
        self.vertices = vertices.len();
    }

    /// Whether there is anything to draw.
    pub fn is_empty(&self) -> bool {
        self.vertices == 0
    }

    /// Draws the positions with the bound (depth) program: attribute 0 is
    /// the position, as shadow.vert reads it.
    pub fn draw_depth(&self, gl: &glow::Context) {
        if self.vertices == 0 {
            return;
        }
        // SAFETY: a draw on the current context.
        unsafe {
            gl.bind_vertex_array(Some(self.vao));
            gl.draw_arrays(glow::TRIANGLES, 0, self.vertices as i32);
            gl.bind_vertex_array(None);
        }
    }

    /// Draws the objects shaded into the bound target with the view
    /// matrix `vp`; `set_lights` binds what light.glsl reads, `bvh` the
    /// scene's BVH and ray records, `probes` the lookup's buffers.
    pub fn draw(
        &self,
        gl: &glow::Context,
        vp: &glam::Mat4,
        view: View,
        bvh: [glow::Buffer; 3],
        probes: Option<&GlProbes>,
        set_lights: impl Fn(glow::Program),
    ) {
        if self.vertices == 0 {
            return;
        }
        // SAFETY: binds, uniforms and a draw on the current context.
        unsafe {
            gl.use_program(Some(self.program));
            let b = glow::SHADER_STORAGE_BUFFER;
            for (k, buf) in [BVH_NODE_BINDING, BVH_TRI_BINDING, RAY_BINDING]
                .iter()
                .zip(bvh)
            {
                gl.bind_buffer_base(b, *k as u32, Some(buf));
            }
            set_lights(self.program);
            if let Some(p) = probes {
                p.bind_lookup(gl, self.program);
            }
            let loc = |s: &str| gl.get_uniform_location(self.program, s);
            gl.uniform_matrix_4_f32_slice(
                loc("view_projection").as_ref(),
                false,
                &vp.to_cols_array(),
            );
            gl.uniform_1_i32(loc("has_probes").as_ref(), probes.is_some() as i32);
            gl.uniform_1_i32(
                loc("view_mode").as_ref(),
                match view {
                    View::Final => 0,
                    View::Direct => 1,
                    View::Indirect => 2,
                    View::Patches => 3,
                    View::Weights => 4,
                },
            );
            gl.bind_vertex_array(Some(self.vao));
            gl.draw_arrays(glow::TRIANGLES, 0, self.vertices as i32);
            gl.bind_vertex_array(None);
        }
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_vertex_array(self.vao);
            gl.delete_buffer(self.vbo);
        }
    }
}

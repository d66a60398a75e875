//! Moving objects on the GPU (`crates/gl/glsl/object.vert`,
//! `crates/gl/glsl/object.frag`): their placed triangles
//! (`radiosity_core::objects`), drawn into the shading pass's target after
//! the scene with the lights' direct light through the shadow maps (which
//! they are drawn into as well, so they cast shadows) and the probes'
//! irradiance (`probe_lookup.glsl`). The CPU reference of the lookup is
//! `radiosity_runtime::probes::Lookup` (tests/gl_probes.rs). The probe view
//! draws a small white sphere at each used probe, shaded by that probe's
//! own irradiance about the sphere's normal.

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

/// A vertex as drawn: the object's, and the probe whose sphere it belongs
/// to in the probe view (−1 for an object).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
struct GpuVertex {
    v: Vertex,
    probe: f32,
}

/// Triangles of a sphere of unit radius (a UV sphere of 16 × 8).
fn unit_sphere() -> Vec<([f32; 3], [f32; 3])> {
    let (seg, rings) = (16, 8);
    let p = |r: usize, s: usize| -> [f32; 3] {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        let ph = 2.0 * std::f32::consts::PI * s as f32 / seg as f32;
        [th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()]
    };
    let mut out = Vec::new();
    for r in 0..rings {
        for s in 0..seg {
            let (a, b, c, d) = (p(r, s), p(r, s + 1), p(r + 1, s + 1), p(r + 1, s));
            for v in [a, b, c, a, c, d] {
                out.push((v, v));
            }
        }
    }
    out
}

/// The objects' geometry (and the probe view's spheres) and program.
pub struct GlObjects {
    pub program: glow::Program,
    /// The objects' and the probe spheres' arrays.
    vao: [glow::VertexArray; 2],
    vbo: [glow::Buffer; 2],
    vertices: [usize; 2],
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
        let make = || -> Result<(glow::VertexArray, glow::Buffer), GlError> {
            // SAFETY: object creation and attribute setup on the current
            // context.
            unsafe {
                let vao = gl.create_vertex_array().map_err(GlError::Call)?;
                let vbo = gl.create_buffer().map_err(GlError::Call)?;
                gl.bind_vertex_array(Some(vao));
                gl.bind_buffer(glow::ARRAY_BUFFER, Some(vbo));
                let stride = std::mem::size_of::<GpuVertex>() as i32;
                for (k, offset) in [0, 12, 24].into_iter().enumerate() {
                    gl.enable_vertex_attrib_array(k as u32);
                    gl.vertex_attrib_pointer_f32(k as u32, 3, glow::FLOAT, false, stride, offset);
                }
                gl.enable_vertex_attrib_array(3);
                gl.vertex_attrib_pointer_f32(3, 1, glow::FLOAT, false, stride, 36);
                gl.bind_vertex_array(None);
                Ok((vao, vbo))
            }
        };
        let (a, b) = (make()?, make()?);
        Ok(GlObjects {
            program,
            vao: [a.0, b.0],
            vbo: [a.1, b.1],
            vertices: [0, 0],
        })
    }

    /// The placed triangles of every object (three vertices a triangle).
    pub fn set(&mut self, gl: &glow::Context, vertices: &[Vertex]) {
        let v: Vec<GpuVertex> = vertices
            .iter()
            .map(|&v| GpuVertex { v, probe: -1.0 })
            .collect();
        self.upload(gl, 0, &v);
    }

    /// The probe view: a white sphere of `radius` at each of `positions`
    /// (probe index, position), shaded with that probe's irradiance alone;
    /// none when empty.
    pub fn set_probe_view(
        &mut self,
        gl: &glow::Context,
        positions: &[(usize, [f64; 3])],
        radius: f32,
    ) {
        let sphere = unit_sphere();
        let mut v = Vec::with_capacity(positions.len() * sphere.len());
        for &(p, c) in positions {
            for &(q, n) in &sphere {
                v.push(GpuVertex {
                    v: Vertex {
                        position: std::array::from_fn(|a| c[a] as f32 + radius * q[a]),
                        normal: n,
                        albedo: [1.0; 3],
                    },
                    probe: p as f32,
                });
            }
        }
        self.upload(gl, 1, &v);
    }

    fn upload(&mut self, gl: &glow::Context, k: usize, v: &[GpuVertex]) {
        // SAFETY: a buffer upload on the current context.
        unsafe {
            gl.bind_buffer(glow::ARRAY_BUFFER, Some(self.vbo[k]));
            gl.buffer_data_u8_slice(glow::ARRAY_BUFFER, bytes_of(v), glow::DYNAMIC_DRAW);
            gl.bind_buffer(glow::ARRAY_BUFFER, None);
        }
        self.vertices[k] = v.len();
    }

    /// Whether there is no object to draw (the probe view aside).
    pub fn is_empty(&self) -> bool {
        self.vertices[0] == 0
    }

    /// Whether nothing at all is drawn.
    pub fn nothing_to_draw(&self) -> bool {
        self.vertices == [0, 0]
    }

    /// Draws the positions with the bound (depth) program: attribute 0 is
    /// the position, as shadow.vert reads it.
    pub fn draw_depth(&self, gl: &glow::Context) {
        if self.vertices[0] == 0 {
            return;
        }
        // SAFETY: a draw on the current context.
        unsafe {
            gl.bind_vertex_array(Some(self.vao[0]));
            gl.draw_arrays(glow::TRIANGLES, 0, self.vertices[0] as i32);
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
        if self.nothing_to_draw() {
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
            gl.uniform_1_i32(loc("view_mode").as_ref(), super::shade::view_mode(view));
            for k in 0..2 {
                if self.vertices[k] > 0 && (k == 0 || probes.is_some()) {
                    gl.bind_vertex_array(Some(self.vao[k]));
                    gl.draw_arrays(glow::TRIANGLES, 0, self.vertices[k] as i32);
                }
            }
            gl.bind_vertex_array(None);
        }
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            for k in 0..2 {
                gl.delete_vertex_array(self.vao[k]);
                gl.delete_buffer(self.vbo[k]);
            }
        }
    }
}

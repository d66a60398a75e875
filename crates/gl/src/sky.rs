//! The sky on the GPU (`crates/gl/glsl/sky.frag` with
//! `crates/gl/glsl/fullscreen.vert`, and the sky terms of
//! `crates/gl/glsl/shade.frag`), following the CPU run time
//! ([`radiosity_runtime::Runtime::set_sky`], [`radiosity_runtime::render`]):
//!
//! - on the patches, `D_sky` ([`radiosity_runtime::sky::irradiance`],
//!   computed on the CPU when the sky changes: one pass over the patches'
//!   stored cells) enters `B0` as `ρ ∘ D_sky` with the emission, so the
//!   gather bounces it; shaped by each cell's open sky
//!   ([`radiosity_runtime::near_field::NearFieldWeights::sky_points`]) it
//!   joins the direct pass's `D` at the lit points, so the near-field
//!   correction sees it as on the CPU;
//! - on the pixels, `D_sky` through the surface map's weights, as `H` is
//!   (shade.frag, binding [`D_SKY_BINDING`]);
//! - behind the scene, each pixel's ray looked up in a latitude-longitude
//!   table of the sky's radiance ([`TABLE`] texels, bilinear), drawn
//!   before the scene. The CPU evaluates the sky exactly per ray; the
//!   table's interpolation is the difference (tests/gl_render.rs bounds
//!   it).

use super::{bytes_of, fill_buffer, storage_buffer, GlError};
use glam::Mat4;
use glow::HasContext;
use radiosity_core::sky::{envmap, Sky};
use radiosity_runtime::sky::SkyError;
use radiosity_runtime::Runtime;
use rayon::prelude::*;

pub const FRAGMENT: &str = include_str!("../glsl/sky.frag");

/// The shading pass's binding of `D_sky` (3 n floats, channel-major).
pub const D_SKY_BINDING: u32 = 11;

/// The background table's size: 1024 × 512 texels (0.35° each), a sun and
/// sky's circumsolar brightening and a gradient's horizon followed to a
/// fraction of a per cent under bilinear lookup.
pub const TABLE: (usize, usize) = (1024, 512);

/// Three channels of one value per patch.
type Channels = [Vec<f32>; 3];

/// The sky's GPU state.
pub struct GlSky {
    program: glow::Program,
    vao: glow::VertexArray,
    table: glow::Texture,
    d_sky: glow::Buffer,
    /// The sky set, `ρ ∘ D_sky` for `B0`, and `D_sky`.
    sky: Option<(Sky, Channels, Channels)>,
}

impl GlSky {
    pub fn new(gl: &glow::Context, n: usize) -> Result<GlSky, GlError> {
        let program = super::tonemap::fullscreen_program(gl, "sky.frag", FRAGMENT)?;
        // SAFETY: object creation on the current context.
        let (vao, table) = unsafe {
            let vao = gl.create_vertex_array().map_err(GlError::Call)?;
            let table = gl.create_texture().map_err(GlError::Call)?;
            gl.bind_texture(glow::TEXTURE_2D, Some(table));
            let p = |k: u32, v: u32| gl.tex_parameter_i32(glow::TEXTURE_2D, k, v as i32);
            p(glow::TEXTURE_MIN_FILTER, glow::LINEAR);
            p(glow::TEXTURE_MAG_FILTER, glow::LINEAR);
            p(glow::TEXTURE_WRAP_S, glow::REPEAT);
            p(glow::TEXTURE_WRAP_T, glow::CLAMP_TO_EDGE);
            gl.bind_texture(glow::TEXTURE_2D, None);
            (vao, table)
        };
        let d_sky = storage_buffer(gl, &vec![0u8; 12 * n.max(1)], glow::DYNAMIC_DRAW)?;
        Ok(GlSky {
            program,
            vao,
            table,
            d_sky,
            sky: None,
        })
    }

    /// The sky of the next frames (`None`: black); refused, as by the CPU
    /// run time, for a bake without sky visibility. Uploads `D_sky` and
    /// the background table.
    pub fn set(
        &mut self,
        gl: &glow::Context,
        rt: &Runtime,
        sky: Option<&Sky>,
    ) -> Result<(), SkyError> {
        let Some(sky) = sky else {
            self.sky = None;
            return Ok(());
        };
        let d = radiosity_runtime::sky::irradiance(&rt.baked, sky)?;
        let flat: Vec<f32> = d.iter().flatten().copied().collect();
        fill_buffer(gl, self.d_sky, bytes_of(&flat), glow::DYNAMIC_DRAW);
        let (w, h) = TABLE;
        let prepared = sky.prepared();
        let texels: Vec<f32> = (0..w * h)
            .into_par_iter()
            .flat_map_iter(|k| {
                let (u, v) = (
                    ((k % w) as f64 + 0.5) / w as f64,
                    ((k / w) as f64 + 0.5) / h as f64,
                );
                let l = prepared.radiance(envmap::direction(u, v));
                [l[0] as f32, l[1] as f32, l[2] as f32, 1.0]
            })
            .collect();
        // SAFETY: an upload of w × h RGBA f32 texels to this context's
        // texture (row 0 first: the top row, v = 0).
        unsafe {
            gl.bind_texture(glow::TEXTURE_2D, Some(self.table));
            gl.tex_image_2d(
                glow::TEXTURE_2D,
                0,
                glow::RGBA32F as i32,
                w as i32,
                h as i32,
                0,
                glow::RGBA,
                glow::FLOAT,
                glow::PixelUnpackData::Slice(Some(bytes_of(&texels))),
            );
            gl.bind_texture(glow::TEXTURE_2D, None);
        }
        let b0 = radiosity_runtime::direct::reflected(&rt.baked, &d);
        self.sky = Some((sky.clone(), b0, d));
        Ok(())
    }

    /// The sky set.
    pub fn sky(&self) -> Option<&Sky> {
        self.sky.as_ref().map(|(s, _, _)| s)
    }

    /// `ρ ∘ D_sky` per channel, when a sky is set.
    pub fn b0(&self) -> Option<&[Vec<f32>; 3]> {
        self.sky.as_ref().map(|(_, b, _)| b)
    }

    /// `D_sky` per channel and patch, when a sky is set.
    pub fn d(&self) -> Option<&[Vec<f32>; 3]> {
        self.sky.as_ref().map(|(_, _, d)| d)
    }

    /// Binds `D_sky` for the shading pass and sets its `has_sky` uniform
    /// in `program` (current).
    pub fn bind(&self, gl: &glow::Context, program: glow::Program) {
        // SAFETY: a bind and a uniform on the current context.
        unsafe {
            gl.bind_buffer_base(glow::SHADER_STORAGE_BUFFER, D_SKY_BINDING, Some(self.d_sky));
            let loc = gl.get_uniform_location(program, "has_sky");
            gl.uniform_1_i32(loc.as_ref(), self.sky.is_some() as i32);
        }
    }

    /// Draws the sky behind the scene into the bound target of `size`,
    /// for the view-projection `vp` from `eye`; nothing without a sky.
    pub fn draw_background(
        &self,
        gl: &glow::Context,
        vp: Mat4,
        eye: [f32; 3],
        size: (usize, usize),
    ) {
        if self.sky.is_none() {
            return;
        }
        // SAFETY: state, binds and one draw on the current context.
        unsafe {
            gl.disable(glow::DEPTH_TEST);
            gl.depth_mask(false);
            gl.use_program(Some(self.program));
            gl.active_texture(glow::TEXTURE0);
            gl.bind_texture(glow::TEXTURE_2D, Some(self.table));
            gl.bind_sampler(0, None);
            let loc = |name: &str| gl.get_uniform_location(self.program, name);
            gl.uniform_1_i32(loc("sky_map").as_ref(), 0);
            gl.uniform_matrix_4_f32_slice(
                loc("inverse_view_projection").as_ref(),
                false,
                &vp.inverse().to_cols_array(),
            );
            gl.uniform_3_f32(loc("eye").as_ref(), eye[0], eye[1], eye[2]);
            gl.uniform_2_f32(loc("size").as_ref(), size.0 as f32, size.1 as f32);
            gl.bind_vertex_array(Some(self.vao));
            gl.draw_arrays(glow::TRIANGLES, 0, 3);
            gl.bind_vertex_array(None);
            gl.enable(glow::DEPTH_TEST);
            gl.depth_mask(true);
        }
    }

    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_vertex_array(self.vao);
            gl.delete_texture(self.table);
            gl.delete_buffer(self.d_sky);
        }
    }
}

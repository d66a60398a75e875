//! Shadow maps (`crates/gl/glsl/shadow.vert`, `crates/gl/glsl/shadow.frag`): every view of
//! every light ([`super::light`]) is one layer of a 32-bit float depth
//! texture array, `resolution` texels a side, read in `crates/gl/glsl/light.glsl`
//! with hardware depth comparison and a 3 × 3 filter. Both sides of the
//! triangles are drawn (either side blocks a shadow ray on the CPU); a
//! constant polygon offset and the shader's normal offset keep surfaces
//! from shadowing themselves ([`super::light::NORMAL_OFFSET`] says why no
//! slope-scaled offset). The CPU reference is the shadow
//! ray of [`radiosity_core::direct::DirectLight::at_points`]; the two differ
//! within a texel or two of shadow edges (tests/gl_render.rs bounds it).

use super::light::ShadowView;
use super::scene::GlScene;
use super::{compile_program, GlError, Stage};
use glow::HasContext;

pub const VERTEX: &str = include_str!("../glsl/shadow.vert");
pub const FRAGMENT: &str = include_str!("../glsl/shadow.frag");

/// The depth-only program (`shadow.vert`, `shadow.frag`: positions
/// through `view_projection`, no colour): the shadow maps' and the
/// shading pass's depth pre-pass.
pub fn depth_program(gl: &glow::Context) -> Result<glow::Program, GlError> {
    compile_program(
        gl,
        &[
            Stage {
                kind: glow::VERTEX_SHADER,
                name: "shadow.vert",
                sources: &[VERTEX],
            },
            Stage {
                kind: glow::FRAGMENT_SHADER,
                name: "shadow.frag",
                sources: &[FRAGMENT],
            },
        ],
        &[],
    )
}

/// Largest shadow map side accepted.
pub const MAX_RESOLUTION: usize = 8192;

/// The shadow maps of the current lights.
pub struct ShadowMaps {
    program: glow::Program,
    framebuffer: glow::Framebuffer,
    /// The depth array, `layers` allocated (at least 1).
    pub texture: glow::Texture,
    /// A sampler comparing with the nearest texel (light.glsl's gate).
    pub nearest: glow::Sampler,
    layers: usize,
    pub resolution: usize,
    /// The most bytes the depth array may take (`None`: what the GL
    /// grants).
    budget: Option<u64>,
}

impl ShadowMaps {
    /// Compiles the pass; maps of `resolution` texels a side, the depth
    /// array within `budget` bytes when one is given (checked before each
    /// allocation: [`GlError::OverBudget`]).
    pub fn new(
        gl: &glow::Context,
        resolution: usize,
        budget: Option<u64>,
    ) -> Result<ShadowMaps, GlError> {
        // SAFETY: a query on the current context.
        let max = unsafe { gl.get_parameter_i32(glow::MAX_TEXTURE_SIZE) }.max(1) as usize;
        if !(16..=MAX_RESOLUTION.min(max)).contains(&resolution) {
            return Err(GlError::Unsupported(format!(
                "shadow map resolution {resolution}: expected 16..={}",
                MAX_RESOLUTION.min(max)
            )));
        }
        let program = depth_program(gl)?;
        // SAFETY: object creation on the current context.
        let (framebuffer, texture, nearest) = unsafe {
            let nearest = gl.create_sampler().map_err(GlError::Call)?;
            let p = |k: u32, v: u32| gl.sampler_parameter_i32(nearest, k, v as i32);
            p(glow::TEXTURE_MIN_FILTER, glow::NEAREST);
            p(glow::TEXTURE_MAG_FILTER, glow::NEAREST);
            p(glow::TEXTURE_WRAP_S, glow::CLAMP_TO_EDGE);
            p(glow::TEXTURE_WRAP_T, glow::CLAMP_TO_EDGE);
            p(glow::TEXTURE_COMPARE_MODE, glow::COMPARE_REF_TO_TEXTURE);
            p(glow::TEXTURE_COMPARE_FUNC, glow::LEQUAL);
            (
                gl.create_framebuffer().map_err(GlError::Call)?,
                gl.create_texture().map_err(GlError::Call)?,
                nearest,
            )
        };
        let mut maps = ShadowMaps {
            program,
            framebuffer,
            texture,
            nearest,
            layers: 0,
            resolution,
            budget,
        };
        maps.allocate(gl, 1)?;
        Ok(maps)
    }

    /// (Re)allocates the depth array with `layers` layers.
    fn allocate(&mut self, gl: &glow::Context, layers: usize) -> Result<(), GlError> {
        let r = self.resolution as i32;
        let what = || {
            format!(
                "the shadow maps: {layers} view{} of {r}² depth texels (points and wide spots take 6 views, other lights 1)",
                if layers == 1 { "" } else { "s" }
            )
        };
        // 4 bytes a texel (DEPTH_COMPONENT32F); saturating, as the layers
        // count the lights' views.
        let bytes = 4u64
            .saturating_mul((r as u64).pow(2))
            .saturating_mul(layers as u64);
        if let Some(budget) = self.budget.filter(|&b| bytes > b) {
            return Err(GlError::OverBudget {
                what: what(),
                bytes,
                budget,
            });
        }
        // SAFETY: a limit query on the current context.
        let max = unsafe { gl.get_parameter_i32(glow::MAX_ARRAY_TEXTURE_LAYERS) };
        if layers > max.max(1) as usize {
            return Err(GlError::Unsupported(format!(
                "{}: more than this OpenGL's {max} array layers",
                what()
            )));
        }
        // SAFETY: texture storage of r × r × layers depth texels on the
        // current context.
        unsafe {
            gl.delete_texture(self.texture);
            let t = gl.create_texture().map_err(GlError::Call)?;
            let a = glow::TEXTURE_2D_ARRAY;
            gl.bind_texture(a, Some(t));
            gl.tex_storage_3d(a, 1, glow::DEPTH_COMPONENT32F, r, r, layers as i32);
            let p = |k: u32, v: u32| gl.tex_parameter_i32(a, k, v as i32);
            p(glow::TEXTURE_MIN_FILTER, glow::LINEAR);
            p(glow::TEXTURE_MAG_FILTER, glow::LINEAR);
            p(glow::TEXTURE_WRAP_S, glow::CLAMP_TO_EDGE);
            p(glow::TEXTURE_WRAP_T, glow::CLAMP_TO_EDGE);
            p(glow::TEXTURE_COMPARE_MODE, glow::COMPARE_REF_TO_TEXTURE);
            p(glow::TEXTURE_COMPARE_FUNC, glow::LEQUAL);
            self.texture = t;
            self.layers = layers;
            match gl.get_error() {
                glow::NO_ERROR => Ok(()),
                glow::OUT_OF_MEMORY => {
                    // Nothing usable was allocated: the next frame tries
                    // again from one layer.
                    self.layers = 0;
                    Err(GlError::OutOfMemory {
                        what: what(),
                        bytes,
                    })
                }
                code => Err(GlError::Call(format!(
                    "allocating {}: GL error 0x{code:x}",
                    what()
                ))),
            }
        }
    }

    /// Renders `scene` into one layer per view, and whatever `more` draws
    /// with the depth program bound (the moving objects).
    pub fn render(
        &mut self,
        gl: &glow::Context,
        scene: &GlScene,
        views: &[ShadowView],
        more: impl Fn(),
    ) -> Result<(), GlError> {
        if views.len() > self.layers {
            self.allocate(gl, views.len())?;
        }
        let r = self.resolution as i32;
        // SAFETY: framebuffer binds, state changes and draws on the current
        // context; the state is restored after.
        unsafe {
            gl.use_program(Some(self.program));
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(self.framebuffer));
            gl.draw_buffers(&[glow::NONE]);
            gl.read_buffer(glow::NONE);
            gl.viewport(0, 0, r, r);
            gl.enable(glow::DEPTH_TEST);
            gl.depth_func(glow::LESS);
            gl.depth_mask(true);
            gl.disable(glow::CULL_FACE);
            gl.enable(glow::POLYGON_OFFSET_FILL);
            gl.polygon_offset(0.0, 1.0);
            let loc = gl.get_uniform_location(self.program, "view_projection");
            for (layer, v) in views.iter().enumerate() {
                gl.framebuffer_texture_layer(
                    glow::FRAMEBUFFER,
                    glow::DEPTH_ATTACHMENT,
                    Some(self.texture),
                    0,
                    layer as i32,
                );
                gl.clear_depth_f32(1.0);
                gl.clear(glow::DEPTH_BUFFER_BIT);
                gl.uniform_matrix_4_f32_slice(
                    loc.as_ref(),
                    false,
                    &v.view_projection.to_cols_array(),
                );
                scene.draw_depth(gl);
                more();
            }
            gl.disable(glow::POLYGON_OFFSET_FILL);
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        }
        super::check(gl, "rendering the shadow maps")
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_framebuffer(self.framebuffer);
            gl.delete_texture(self.texture);
            gl.delete_sampler(self.nearest);
        }
    }
}

//! The shading pass (`crates/gl/glsl/shade.vert`, `crates/gl/glsl/shade.frag` with
//! `crates/gl/glsl/light.glsl` and `crates/gl/glsl/surface.glsl`): the scene's triangles from
//! the camera into a linear RGBA32F image — `H` from the surface map per
//! fragment, `D` from the shadow maps per fragment, the full-resolution
//! albedo texture — then read back and tone-mapped by the CPU's code
//! ([`radiosity_runtime::tonemap`]), so the two back ends share one exposure
//! and curve. Its CPU reference is [`radiosity_runtime::render`], one
//! primary ray per pixel centre: rasterisation samples the same centres.

use super::scene::GlScene;
use super::sky::GlSky;
use super::surface::GlSurfaceMap;
use super::{compile_program, GlError, Stage};
use glam::camera::rh::{proj::opengl, view::look_at_mat4};
use glam::{Mat4, Vec3};
use glow::HasContext;
use radiosity_core::math::{cross, normalize, sub};
use radiosity_core::scene_config::Camera;
use radiosity_runtime::render::{Image, View};

pub const VERTEX: &str = include_str!("../glsl/shade.vert");
pub const FRAGMENT: &str = include_str!("../glsl/shade.frag");
pub const SURFACE: &str = include_str!("../glsl/surface.glsl");

/// One material's constants for a draw.
#[derive(Clone, Debug)]
pub struct MaterialConstants {
    pub kd: [f32; 3],
    pub albedo: [f32; 3],
    /// `Le = s Ke / π` with the frame's emission scale `s`.
    pub emitted: [f32; 3],
}

/// The pass and its render target.
pub struct Shade {
    pub program: glow::Program,
    framebuffer: glow::Framebuffer,
    /// The RGBA32F radiance texture (sampled by the tone-mapping pass).
    pub color: Option<glow::Texture>,
    depth: Option<glow::Renderbuffer>,
    size: (usize, usize),
    /// A bilinear sampler without mipmaps (repeat wrapping): bound over
    /// the textures' own mipmapped filtering when [`Shade::mipmaps`] is
    /// off, so that a texel is filtered as the CPU renderer filters it
    /// ([`radiosity_runtime::texture::Texture::sample`]).
    bilinear: glow::Sampler,
    /// Sample albedo textures with their mipmaps (trilinear: no shimmer
    /// under minification, the viewer's choice), or bilinearly from the
    /// full-resolution level as the CPU reference does (`render`,
    /// comparisons).
    pub mipmaps: bool,
    /// The depth pre-pass's program (`shadow.vert`/`shadow.frag`: position
    /// only, depth only), and whether it runs ([`Shade::draw`]).
    depth_program: glow::Program,
    pub depth_prepass: bool,
}

/// Where the camera's projection puts the near and far planes for a scene
/// within `lo..hi`: far just beyond the farthest corner, near at 1e-3 of
/// it (a 32-bit float depth buffer then resolves 6e-5 of the far distance
/// there, far below a pixel's footprint).
fn planes(eye: Vec3, lo: [f32; 3], hi: [f32; 3]) -> (f32, f32) {
    let far = (0..8)
        .map(|k| {
            let c = Vec3::new(
                if k & 1 == 0 { lo[0] } else { hi[0] },
                if k & 2 == 0 { lo[1] } else { hi[1] },
                if k & 4 == 0 { lo[2] } else { hi[2] },
            );
            (c - eye).length()
        })
        .fold(0.0f32, f32::max)
        .max(1e-20)
        * 1.01;
    (1e-3 * far, far)
}

/// The camera's view-projection for an image `width × height`, matching
/// the CPU renderer's rays ([`radiosity_runtime::render::Rays`]).
pub fn camera_matrix(
    camera: &Camera,
    width: usize,
    height: usize,
    lo: [f32; 3],
    hi: [f32; 3],
) -> Mat4 {
    let eye = Vec3::from(camera.position);
    let f = normalize(sub(
        camera.target.map(f64::from),
        camera.position.map(f64::from),
    ));
    let right = normalize(cross(f, camera.up.map(f64::from)));
    let up = cross(right, f);
    let (near, far) = planes(eye, lo, hi);
    let view = look_at_mat4(
        eye,
        eye + Vec3::new(f[0] as f32, f[1] as f32, f[2] as f32),
        Vec3::new(up[0] as f32, up[1] as f32, up[2] as f32),
    );
    let proj = opengl::perspective(
        camera.fov_y_deg.to_radians(),
        width as f32 / height as f32,
        near,
        far,
    );
    proj * view
}

/// The `view_mode` uniform of `view` (shade.frag and object.frag: 0 final,
/// 1 direct, 2 indirect, 3 patches, 4 weights).
pub fn view_mode(view: View) -> i32 {
    match view {
        View::Final => 0,
        View::Direct => 1,
        View::Indirect => 2,
        View::Patches => 3,
        View::Weights => 4,
    }
}

impl Shade {
    pub fn new(gl: &glow::Context, defines: &[(&str, usize)]) -> Result<Shade, GlError> {
        let light = super::direct::LIGHT;
        let program = compile_program(
            gl,
            &[
                Stage {
                    kind: glow::VERTEX_SHADER,
                    name: "shade.vert",
                    sources: &[VERTEX],
                },
                Stage {
                    kind: glow::FRAGMENT_SHADER,
                    name: "shade.frag",
                    sources: &[light, SURFACE, FRAGMENT],
                },
            ],
            defines,
        )?;
        let depth_program = super::shadow::depth_program(gl)?;
        // SAFETY: object creation on the current context.
        let (framebuffer, bilinear) = unsafe {
            let bilinear = gl.create_sampler().map_err(GlError::Call)?;
            let p = |k: u32, v: u32| gl.sampler_parameter_i32(bilinear, k, v as i32);
            p(glow::TEXTURE_MIN_FILTER, glow::LINEAR);
            p(glow::TEXTURE_MAG_FILTER, glow::LINEAR);
            p(glow::TEXTURE_WRAP_S, glow::REPEAT);
            p(glow::TEXTURE_WRAP_T, glow::REPEAT);
            (gl.create_framebuffer().map_err(GlError::Call)?, bilinear)
        };
        Ok(Shade {
            program,
            framebuffer,
            color: None,
            depth: None,
            size: (0, 0),
            bilinear,
            mipmaps: true,
            depth_program,
            depth_prepass: true,
        })
    }

    /// The render target's size.
    pub fn size(&self) -> (usize, usize) {
        self.size
    }

    /// Makes the render target `width × height`.
    fn target(&mut self, gl: &glow::Context, width: usize, height: usize) -> Result<(), GlError> {
        if self.size == (width, height) {
            return Ok(());
        }
        // SAFETY: renderbuffer storage and attachment on the current
        // context.
        unsafe {
            let max = gl.get_parameter_i32(glow::MAX_RENDERBUFFER_SIZE).max(1) as usize;
            if width == 0 || height == 0 || width > max || height > max {
                return Err(GlError::Unsupported(format!(
                    "an image of {width} x {height} pixels: this GL renders up to {max} a side"
                )));
            }
            if let Some(t) = self.color.take() {
                gl.delete_texture(t);
            }
            if let Some(rb) = self.depth.take() {
                gl.delete_renderbuffer(rb);
            }
            let color = gl.create_texture().map_err(GlError::Call)?;
            gl.bind_texture(glow::TEXTURE_2D, Some(color));
            gl.tex_storage_2d(
                glow::TEXTURE_2D,
                1,
                glow::RGBA32F,
                width as i32,
                height as i32,
            );
            let nearest = glow::NEAREST as i32;
            gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MIN_FILTER, nearest);
            gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MAG_FILTER, nearest);
            let depth = gl.create_renderbuffer().map_err(GlError::Call)?;
            gl.bind_renderbuffer(glow::RENDERBUFFER, Some(depth));
            gl.renderbuffer_storage(
                glow::RENDERBUFFER,
                glow::DEPTH_COMPONENT32F,
                width as i32,
                height as i32,
            );
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(self.framebuffer));
            gl.framebuffer_texture_2d(
                glow::FRAMEBUFFER,
                glow::COLOR_ATTACHMENT0,
                glow::TEXTURE_2D,
                Some(color),
                0,
            );
            gl.framebuffer_renderbuffer(
                glow::FRAMEBUFFER,
                glow::DEPTH_ATTACHMENT,
                glow::RENDERBUFFER,
                Some(depth),
            );
            let status = gl.check_framebuffer_status(glow::FRAMEBUFFER);
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            if status != glow::FRAMEBUFFER_COMPLETE {
                return Err(GlError::Call(format!(
                    "the shading target is incomplete (status 0x{status:x})"
                )));
            }
            self.color = Some(color);
            self.depth = Some(depth);
            self.size = (width, height);
        }
        Ok(())
    }

    /// Draws `view` from `camera` into the render target (`width ×
    /// height`), the sky behind the scene and on its pixels (final and
    /// direct views). The caller has bound the lights, views, shadow maps
    /// (texture unit 1), `H` (binding 6) and the patch albedo (binding 7),
    /// and sets the light uniforms through `set_lights`.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        gl: &glow::Context,
        scene: &GlScene,
        map: &GlSurfaceMap,
        sky: &GlSky,
        materials: &[MaterialConstants],
        camera: &Camera,
        view: View,
        (width, height): (usize, usize),
        n: usize,
        set_lights: impl Fn(glow::Program),
    ) -> Result<(), GlError> {
        self.target(gl, width, height)?;
        let vp = camera_matrix(camera, width, height, scene.lo, scene.hi);
        // SAFETY: state, binds, uniforms and draws on the current context.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(self.framebuffer));
            gl.draw_buffers(&[glow::COLOR_ATTACHMENT0]);
            gl.viewport(0, 0, width as i32, height as i32);
            gl.enable(glow::DEPTH_TEST);
            gl.depth_func(glow::LESS);
            gl.depth_mask(true);
            gl.disable(glow::CULL_FACE);
            gl.clear_color(0.0, 0.0, 0.0, 0.0);
            gl.clear_depth_f32(1.0);
            gl.clear(glow::COLOR_BUFFER_BIT | glow::DEPTH_BUFFER_BIT);
            let sky_seen = matches!(view, View::Final | View::Direct);
            if sky_seen {
                sky.draw_background(gl, vp, camera.position, (width, height));
            }
            if self.depth_prepass {
                // Depth first, positions only: the shading pass below then
                // runs its fragment shader (surface map, every light's
                // filtered shadow maps, the albedo texture) once per pixel,
                // for the nearest surface, instead of once per fragment
                // drawn. The two vertex shaders compute gl_Position alike
                // (`invariant`), so the nearest fragment passes EQUAL.
                gl.use_program(Some(self.depth_program));
                gl.color_mask(false, false, false, false);
                let loc = gl.get_uniform_location(self.depth_program, "view_projection");
                gl.uniform_matrix_4_f32_slice(loc.as_ref(), false, &vp.to_cols_array());
                scene.draw_depth(gl);
                gl.color_mask(true, true, true, true);
                gl.depth_func(glow::EQUAL);
                gl.depth_mask(false);
            }
            gl.use_program(Some(self.program));
            gl.bind_buffer_base(glow::SHADER_STORAGE_BUFFER, 0, Some(scene.normals));
            map.bind(gl, self.program);
            sky.bind(gl, self.program);
            set_lights(self.program);
            let loc = |name: &str| gl.get_uniform_location(self.program, name);
            gl.uniform_matrix_4_f32_slice(
                loc("view_projection").as_ref(),
                false,
                &vp.to_cols_array(),
            );
            let e = camera.position;
            gl.uniform_3_f32(loc("eye").as_ref(), e[0], e[1], e[2]);
            gl.uniform_1_u32(loc("n").as_ref(), n as u32);
            gl.uniform_1_f32(
                loc("albedo_max").as_ref(),
                radiosity_core::scene::ALBEDO_MAX,
            );
            gl.uniform_1_i32(loc("view_mode").as_ref(), view_mode(view));
            gl.uniform_1_i32(loc("albedo_texture").as_ref(), 0);
            gl.bind_sampler(0, (!self.mipmaps).then_some(self.bilinear));
            gl.bind_vertex_array(Some(scene.vao));
            for d in &scene.draws {
                let m = &materials[d.material];
                gl.uniform_3_f32(loc("kd").as_ref(), m.kd[0], m.kd[1], m.kd[2]);
                let a = m.albedo;
                gl.uniform_3_f32(loc("material_albedo").as_ref(), a[0], a[1], a[2]);
                let l = m.emitted;
                gl.uniform_3_f32(loc("emitted").as_ref(), l[0], l[1], l[2]);
                let tex = scene.textures[d.material];
                gl.uniform_1_i32(loc("has_texture").as_ref(), tex.is_some() as i32);
                gl.active_texture(glow::TEXTURE0);
                gl.bind_texture(glow::TEXTURE_2D, tex);
                gl.draw_arrays(glow::TRIANGLES, d.first_vertex as i32, d.vertices as i32);
            }
            gl.bind_vertex_array(None);
            gl.bind_sampler(0, None);
            gl.depth_func(glow::LESS);
            gl.depth_mask(true);
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        }
        super::check(gl, "shading")
    }

    /// Runs `f` with the render target bound (as [`Shade::draw`] left it),
    /// depth-tested and written: more geometry drawn into the image.
    pub fn draw_more(&self, gl: &glow::Context, f: impl FnOnce()) {
        let (w, h) = self.size;
        // SAFETY: state and binds on the current context, restored after.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(self.framebuffer));
            gl.viewport(0, 0, w as i32, h as i32);
            gl.enable(glow::DEPTH_TEST);
            gl.depth_func(glow::LESS);
            gl.depth_mask(true);
            f();
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        }
    }

    /// The render target read back (blocking): linear radiance, top row
    /// first, and the covered flags.
    pub fn read(&self, gl: &glow::Context) -> Image {
        let (w, h) = self.size;
        // SAFETY: makes the draw's writes visible to the read.
        unsafe { gl.memory_barrier(glow::FRAMEBUFFER_BARRIER_BIT) };
        let mut bytes = vec![0u8; 16 * w * h];
        // SAFETY: a read of w × h RGBA f32 pixels of the bound target.
        unsafe {
            gl.bind_framebuffer(glow::READ_FRAMEBUFFER, Some(self.framebuffer));
            gl.read_buffer(glow::COLOR_ATTACHMENT0);
            gl.pixel_store_i32(glow::PACK_ALIGNMENT, 4);
            gl.read_pixels(
                0,
                0,
                w as i32,
                h as i32,
                glow::RGBA,
                glow::FLOAT,
                glow::PixelPackData::Slice(Some(&mut bytes)),
            );
            gl.bind_framebuffer(glow::READ_FRAMEBUFFER, None);
        }
        let px: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let mut img = Image {
            width: w,
            height: h,
            radiance: Vec::with_capacity(w * h),
            covered: Vec::with_capacity(w * h),
        };
        // GL's rows are bottom first.
        for y in (0..h).rev() {
            for x in 0..w {
                let p = &px[4 * (y * w + x)..4 * (y * w + x) + 4];
                img.radiance.push([p[0], p[1], p[2]]);
                img.covered.push(p[3] > 0.5);
            }
        }
        img
    }

    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_program(self.depth_program);
            gl.delete_framebuffer(self.framebuffer);
            gl.delete_sampler(self.bilinear);
            if let Some(t) = self.color {
                gl.delete_texture(t);
            }
            if let Some(rb) = self.depth {
                gl.delete_renderbuffer(rb);
            }
        }
    }
}

//! The run time on the GPU, one frame at a time: shadow maps
//! ([`super::shadow`]), direct light on patches and `B0`
//! ([`super::direct`]), the compressed gather `H = T̃ · B0`
//! ([`super::gather`]), all on the GPU without a round trip; then the
//! shading pass ([`super::shade`]) draws any view from any camera. Each
//! pass is timed with GPU timer queries, read back when they are ready
//! (never waited for), so timing does not stall the pipeline.
//!
//! **What a frame skips.** When the lights and emission scales are those
//! of the last frame, the shadow, direct and gather passes are not run
//! (the buffers hold their results); the gather reads only the tile
//! columns of `B0` that are non-zero (flagged by the direct pass). The CPU
//! run time ([`radiosity_runtime::Runtime`]) defines every quantity and is
//! the reference of the tests (tests/gl_render.rs).
//!
//! **`H` from the CPU.** [`GlRenderer::frame_with_h`] takes the CPU run
//! time's `H` instead of computing the patch light here: only the shadow
//! maps (for the shading's direct light) run, for GL implementations that
//! compute slowly (a software rasterizer), where the viewer chooses it.

use super::direct::{GlDirect, LIGHT_BINDING, VIEW_BINDING};
use super::gather::GlGather;
use super::light::{Packed, NORMAL_OFFSET};
use super::near_field::{GlNearField, NearFieldInputs};
use super::scene::GlScene;
use super::shade::{MaterialConstants, Shade};
use super::shadow::ShadowMaps;
use super::sky::GlSky;
use super::surface::GlSurfaceMap;
use super::{bytes_of, fill_buffer, read_floats, storage_buffer, GlError};
use glow::HasContext;
use radiosity_bakefile::surface::SAMPLES_PER_PATCH;
use radiosity_core::scene_config::{Camera, Light};
use radiosity_runtime::emission::Emission;
use radiosity_runtime::render::{Image, View};
use radiosity_runtime::Runtime;
use std::collections::BTreeMap;
use std::f32::consts::PI;

/// Options of the GL run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlOptions {
    /// Shadow map side in texels.
    pub shadow_resolution: usize,
    /// Sample points per patch for direct light (1..=16). With a bake's
    /// near-field correction, its weights are made for the count given
    /// when the renderer is made, and that count stays in use.
    pub samples: usize,
    /// Skip zero tile columns of `B0` in the gather (off only to measure
    /// what it saves: the result is the same up to the order of the
    /// gather's f32 sums, `crates/gl/src/gather.rs`).
    pub skip_columns: bool,
    /// Skip the frame's passes when nothing changed.
    pub cache: bool,
    /// The most bytes the shadow maps may take (`None`: what the GL
    /// grants; a frame whose lights need more fails with
    /// [`GlError::OverBudget`] before allocating, and the renderer goes on
    /// with other lights).
    pub shadow_budget: Option<u64>,
    /// Sample albedo textures with mipmaps (the viewer), or bilinearly at
    /// full resolution as the CPU renderer does (`render`, comparisons
    /// with it): the two differ where a texture is minified.
    pub mipmaps: bool,
    /// Draw the camera's depth before shading (off only to measure what it
    /// saves: the same image but where coplanar surfaces overlap exactly).
    pub depth_prepass: bool,
}

impl Default for GlOptions {
    fn default() -> Self {
        GlOptions {
            shadow_resolution: 2048,
            samples: radiosity_runtime::direct::DEFAULT_SAMPLES,
            skip_columns: true,
            cache: true,
            shadow_budget: None,
            mipmaps: true,
            depth_prepass: true,
        }
    }
}

/// The passes timed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pass {
    Shadow = 0,
    Direct = 1,
    Gather = 2,
    Shade = 3,
}

pub const PASSES: [&str; 4] = ["shadow maps", "direct", "gather", "shading"];

/// What one frame did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GlFrameStats {
    /// Nothing changed: no pass ran.
    pub unchanged: bool,
    pub lights: usize,
    /// Shadow map views rendered.
    pub views: usize,
}

/// GPU timer queries per pass, read when ready: a timestamp before and
/// after each pass (`glQueryCounter`; Mesa's llvmpipe reports
/// `GL_TIME_ELAPSED` from a zero start, timestamps are right on every
/// driver tried).
struct Timers {
    pending: Vec<(Pass, glow::Query, glow::Query)>,
    free: Vec<glow::Query>,
    open: Option<(Pass, glow::Query)>,
    /// The latest result of each pass, milliseconds.
    last: [Option<f64>; 4],
}

impl Timers {
    fn query(&mut self, gl: &glow::Context) -> Option<glow::Query> {
        // SAFETY: query creation on the current context.
        self.free
            .pop()
            .or_else(|| unsafe { gl.create_query() }.ok())
    }

    fn begin(&mut self, gl: &glow::Context, pass: Pass) {
        if let Some(q) = self.query(gl) {
            // SAFETY: a timestamp query on the current context.
            unsafe { gl.query_counter(q, glow::TIMESTAMP) };
            self.open = Some((pass, q));
        }
    }

    fn end(&mut self, gl: &glow::Context) {
        if let Some((pass, q0)) = self.open.take() {
            match self.query(gl) {
                Some(q1) => {
                    // SAFETY: a timestamp query on the current context.
                    unsafe { gl.query_counter(q1, glow::TIMESTAMP) };
                    self.pending.push((pass, q0, q1));
                }
                None => self.free.push(q0),
            }
        }
    }

    /// Forgets `pass`'s time and the queries still pending for it: a frame
    /// that does not run the pass (the CPU computed it) must not show the
    /// time of an earlier one.
    fn forget(&mut self, pass: Pass) {
        self.last[pass as usize] = None;
        // In place: this runs on every frame the CPU lights.
        let free = &mut self.free;
        self.pending.retain(|&(p, q0, q1)| {
            if p == pass {
                free.extend([q0, q1]);
            }
            p != pass
        });
    }

    /// Reads the results that are ready (all of them when `wait`).
    fn poll(&mut self, gl: &glow::Context, wait: bool) {
        let mut keep = Vec::new();
        for (pass, q0, q1) in self.pending.drain(..) {
            // SAFETY: result queries of issued timestamps; the u64 results
            // are written to locals (no query buffer is bound).
            unsafe {
                let ready =
                    wait || gl.get_query_parameter_u32(q1, glow::QUERY_RESULT_AVAILABLE) != 0;
                if ready {
                    self.last[pass as usize] = Some(super::elapsed_ns(gl, q0, q1) as f64 * 1e-6);
                    self.free.extend([q0, q1]);
                } else {
                    keep.push((pass, q0, q1));
                }
            }
        }
        self.pending = keep;
    }
}

/// The lights, views and shadow maps light.glsl reads.
#[derive(Clone, Copy)]
struct LightBinding {
    lights: glow::Buffer,
    views: glow::Buffer,
    maps: glow::Texture,
    /// A nearest-texel comparison sampler for the same maps.
    nearest: glow::Sampler,
    count: i32,
    lift: f32,
}

impl LightBinding {
    /// Binds them and sets light.glsl's uniforms in `program` (current).
    fn bind(&self, gl: &glow::Context, program: glow::Program) {
        // SAFETY: binds and uniforms on the current context.
        unsafe {
            let b = glow::SHADER_STORAGE_BUFFER;
            gl.bind_buffer_base(b, LIGHT_BINDING as u32, Some(self.lights));
            gl.bind_buffer_base(b, VIEW_BINDING as u32, Some(self.views));
            gl.active_texture(glow::TEXTURE1);
            gl.bind_texture(glow::TEXTURE_2D_ARRAY, Some(self.maps));
            gl.active_texture(glow::TEXTURE2);
            gl.bind_texture(glow::TEXTURE_2D_ARRAY, Some(self.maps));
            gl.bind_sampler(2, Some(self.nearest));
            gl.active_texture(glow::TEXTURE0);
            let loc = |name: &str| gl.get_uniform_location(program, name);
            gl.uniform_1_i32(loc("shadow_maps").as_ref(), 1);
            gl.uniform_1_i32(loc("shadow_nearest").as_ref(), 2);
            gl.uniform_1_i32(loc("light_count").as_ref(), self.count);
            gl.uniform_1_f32(loc("normal_offset").as_ref(), NORMAL_OFFSET);
            gl.uniform_1_f32(loc("lift").as_ref(), self.lift);
        }
    }
}

/// A baked scene on the GPU, ready for frames.
pub struct GlRenderer {
    pub scene: GlScene,
    map: GlSurfaceMap,
    shadows: ShadowMaps,
    direct: GlDirect,
    pub gather: GlGather,
    near: Option<GlNearField>,
    shade: Shade,
    sky: GlSky,
    /// The irradiance probes (none when the bake has none) and the moving
    /// objects lit by them; whether the objects moved since the shadow
    /// maps were drawn.
    probes: Option<super::probes::GlProbes>,
    objects: super::objects::GlObjects,
    objects_moved: bool,
    /// The sky changed since the emission buffer (which carries the sky's
    /// `ρ ∘ D_sky` into `B0`) was last uploaded.
    sky_changed: bool,
    /// `H`'s deviation in the patches' face cells is in the near-field pass's
    /// buffer for the last frame (shade.frag adds it per pixel).
    h_points: bool,
    lights_buffer: glow::Buffer,
    views_buffer: glow::Buffer,
    packed: Packed,
    emission: Emission,
    materials: Vec<radiosity_core::scene::Material>,
    /// The last frame's lights and scales, and whether its `H` came
    /// from the CPU ([`GlRenderer::frame_with_h`]).
    last: Option<(Vec<Light>, BTreeMap<String, f32>, bool)>,
    last_scales: Option<BTreeMap<String, f32>>,
    lift: f32,
    n: usize,
    timers: Timers,
    pub options: GlOptions,
}

impl GlRenderer {
    /// Uploads the run time's bake and scene (the context must be current).
    pub fn new(
        gl: &glow::Context,
        rt: &Runtime,
        options: GlOptions,
    ) -> Result<GlRenderer, GlError> {
        let baked = &rt.baked;
        let n = rt.n();
        let scene = GlScene::new(gl, &rt.scene)?;
        let map = GlSurfaceMap::new(gl, &baked.surface_map)?;
        let shadows = ShadowMaps::new(gl, options.shadow_resolution, options.shadow_budget)?;
        let direct = GlDirect::new(
            gl,
            baked,
            rt.direct.bvh(),
            rt.direct.offset(),
            rt.direct.far(),
        )?;
        let gather = GlGather::new(gl, &baked.matrix)?;
        let near = GlNearField::new(gl, &rt.near_field_weights(options.samples))?;
        let shade = Shade::new(
            gl,
            &[
                ("LIGHT_BINDING", LIGHT_BINDING),
                ("VIEW_BINDING", VIEW_BINDING),
                ("SAMPLES_PER_PATCH", SAMPLES_PER_PATCH),
            ],
        )?;
        let materials = rt.scene.materials.clone();
        let sky = GlSky::new(gl, n)?;
        let probes = if baked.probes.is_empty() {
            None
        } else {
            Some(super::probes::GlProbes::new(
                gl,
                &radiosity_runtime::probes::Decoded::new(&baked.probes),
                baked.probes.grid,
                n,
            )?)
        };
        let objects = super::objects::GlObjects::new(gl)?;
        Ok(GlRenderer {
            scene,
            map,
            shadows,
            direct,
            gather,
            near,
            shade,
            sky,
            probes,
            objects,
            objects_moved: false,
            sky_changed: false,
            h_points: false,
            lights_buffer: storage_buffer(gl, &[], glow::DYNAMIC_DRAW)?,
            views_buffer: storage_buffer(gl, &[], glow::DYNAMIC_DRAW)?,
            packed: Packed::default(),
            emission: Emission::new(baked, &rt.scene),
            materials,
            last: None,
            last_scales: None,
            lift: rt.direct.offset() as f32,
            n,
            timers: Timers {
                pending: Vec::new(),
                free: Vec::new(),
                open: None,
                last: [None; 4],
            },
            options,
        })
    }

    /// What light.glsl needs bound.
    fn light_binding(&self) -> LightBinding {
        LightBinding {
            lights: self.lights_buffer,
            views: self.views_buffer,
            maps: self.shadows.texture,
            nearest: self.shadows.nearest,
            count: (self.packed.lights.len() / super::light::LIGHT_WORDS) as i32,
            lift: self.lift,
        }
    }

    /// Lights the scene: shadow maps, `D`, `B0` and `H` on the GPU (module
    /// doc for what is skipped). Nothing is read back.
    pub fn frame(
        &mut self,
        gl: &glow::Context,
        lights: &[Light],
        scales: &BTreeMap<String, f32>,
    ) -> Result<GlFrameStats, GlError> {
        let stats = self.start_frame(gl, lights, scales, false)?;
        if stats.unchanged {
            return Ok(stats);
        }
        if self.last_scales.as_ref() != Some(scales) || self.sky_changed {
            // The sky's `ρ ∘ D_sky` rides with the emission into `B0`.
            let mut e = self.emission.exitance(self.n, scales);
            if let Some(p) = &mut self.probes {
                // The probes see the emission apart (their emission
                // entries): the patches' part and the materials'.
                let emitted = radiosity_runtime::probes::emitted(&self.materials, scales);
                p.set_emission(gl, &e, &emitted);
            }
            if let Some(b) = self.sky.b0() {
                for (ec, bc) in e.iter_mut().zip(b) {
                    for (x, y) in ec.iter_mut().zip(bc) {
                        *x += y;
                    }
                }
            }
            self.direct.set_emission(gl, &e);
            if self.sky_changed {
                // And at the lit points, for the near-field correction
                // (a change of emission alone leaves them).
                let points = self
                    .near
                    .as_ref()
                    .zip(self.sky.d())
                    .and_then(|(nf, d)| nf.sky_points(d));
                self.direct.set_sky_points(gl, points.as_deref());
            }
            self.last_scales = Some(scales.clone());
            self.sky_changed = false;
        }
        self.timers.begin(gl, Pass::Direct);
        let samples = self
            .near
            .as_ref()
            .map_or(self.options.samples, |nf| nf.samples());
        let binding = self.light_binding();
        self.direct.dispatch(gl, samples, |p| binding.bind(gl, p));
        self.timers.end(gl);
        let io = NearFieldInputs {
            d_points: self.direct.d_points_buffer(),
            albedo: self.direct.albedo_buffer(),
            b0: self.direct.b0_buffer(),
            active: self.direct.active_buffer(),
            h: self.gather.h_buffer(),
        };
        if let Some(nf) = &self.near {
            nf.dispatch(gl, 0, &io);
        }
        if !self.options.skip_columns {
            self.direct.activate_all(gl);
        }
        // SAFETY: a barrier between the direct pass's writes and the
        // gather's reads.
        unsafe { gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT) };
        self.timers.begin(gl, Pass::Gather);
        let input = self
            .near
            .as_ref()
            .map_or(self.direct.b0_buffer(), |nf| nf.gather_input());
        self.gather.dispatch(gl, input, self.direct.active_buffer());
        if let Some(nf) = &self.near {
            nf.dispatch(gl, 1, &io);
            if nf.has_receiver() {
                nf.dispatch(gl, 2, &io);
            }
        }
        self.h_points = self.near.as_ref().is_some_and(|nf| nf.has_receiver());
        if let Some(p) = &self.probes {
            // SAFETY: a barrier between the gather's writes and the probes'
            // reads.
            unsafe { gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT) };
            p.dispatch(
                gl,
                self.direct.b0_buffer(),
                self.gather.h_buffer(),
                self.direct.albedo_buffer(),
            );
        }
        self.timers.end(gl);
        // SAFETY: the gather's writes are read by the shading pass.
        unsafe { gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT) };
        super::check(gl, "the frame")?;
        self.last = Some((lights.to_vec(), scales.clone(), false));
        Ok(stats)
    }

    /// What both kinds of frame do first: the timers read, and either
    /// nothing (the same `lights`, `scales` and kind of frame as the last:
    /// the stats say `unchanged`) or the shadow maps rendered.
    fn start_frame(
        &mut self,
        gl: &glow::Context,
        lights: &[Light],
        scales: &BTreeMap<String, f32>,
        cpu: bool,
    ) -> Result<GlFrameStats, GlError> {
        self.timers.poll(gl, false);
        let mut stats = GlFrameStats {
            lights: lights.len(),
            ..GlFrameStats::default()
        };
        stats.unchanged = self.options.cache
            && self
                .last
                .as_ref()
                .is_some_and(|(l, s, c)| l == lights && s == scales && *c == cpu);
        if !stats.unchanged {
            stats.views = self.shadow_maps(gl, lights)?;
        } else if self.objects_moved {
            // The same light, moved objects: their shadows drawn again.
            let objects = &self.objects;
            self.shadows
                .render(gl, &self.scene, &self.packed.views, || {
                    objects.draw_depth(gl)
                })?;
        }
        self.objects_moved = false;
        Ok(stats)
    }

    /// The lights packed and uploaded, and their shadow maps rendered (the
    /// shading pass's direct light reads them); returns the views drawn.
    fn shadow_maps(&mut self, gl: &glow::Context, lights: &[Light]) -> Result<usize, GlError> {
        // The buffers now change: until this frame completes, no earlier
        // frame's lights describe them (a frame that fails here, say with
        // too many shadow views, must not leave the next frame of the
        // earlier lights believing nothing changed).
        self.last = None;
        let res = self.shadows.resolution;
        self.packed = Packed::new(lights, self.scene.lo, self.scene.hi, res);
        self.direct.set_lights(gl, lights);
        fill_buffer(
            gl,
            self.lights_buffer,
            bytes_of(&self.packed.lights),
            glow::DYNAMIC_DRAW,
        );
        fill_buffer(
            gl,
            self.views_buffer,
            bytes_of(&self.packed.view_words(res)),
            glow::DYNAMIC_DRAW,
        );
        self.timers.begin(gl, Pass::Shadow);
        let objects = &self.objects;
        self.shadows
            .render(gl, &self.scene, &self.packed.views, || {
                objects.draw_depth(gl)
            })?;
        self.timers.end(gl);
        Ok(self.packed.views.len())
    }

    /// A frame whose patch light was computed elsewhere: `h` is the CPU
    /// run time's `H` of the same `lights` and `scales`
    /// ([`Runtime::frame`], three channels of `n`), uploaded for the
    /// shading pass; only the shadow maps are rendered here (the shading
    /// pass's direct light at pixels). The direct, near-field and gather
    /// passes do not run, so [`GlRenderer::d`] and [`GlRenderer::b0`] do
    /// not describe this frame. Where GL is slow at compute (a software
    /// rasterizer: llvmpipe's gather, 214–267 ms on the Cornell box at 3,940
    /// patches against the CPU's 0.5–0.9 ms, `bench frame`) this keeps the
    /// window interactive. Nothing runs when nothing changed.
    pub fn frame_with_h(
        &mut self,
        gl: &glow::Context,
        lights: &[Light],
        scales: &BTreeMap<String, f32>,
        h: &[Vec<f32>; 3],
        h_points: Option<&[Vec<f32>; 3]>,
    ) -> Result<GlFrameStats, GlError> {
        if h.iter().any(|c| c.len() != self.n) {
            return Err(GlError::Call(format!(
                "H of {} patches given to a renderer of {}",
                h[0].len(),
                self.n
            )));
        }
        let stats = self.start_frame(gl, lights, scales, true)?;
        if stats.unchanged {
            return Ok(stats);
        }
        // Direct light on the patches and the gather ran on the CPU.
        self.timers.forget(Pass::Direct);
        self.timers.forget(Pass::Gather);
        // SAFETY: uploads of n floats per channel into the gather's output
        // buffer, which holds exactly 3 n (channel-major), on the current
        // context.
        unsafe {
            gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(self.gather.h_buffer()));
            for (c, channel) in h.iter().enumerate() {
                let offset = (c * 4 * self.n) as i32;
                gl.buffer_sub_data_u8_slice(glow::SHADER_STORAGE_BUFFER, offset, bytes_of(channel));
            }
        }
        // And H's deviation in the face cells, where this renderer has room.
        self.h_points = false;
        if let (Some(p), Some(nf)) = (h_points, self.near.as_ref().filter(|nf| nf.has_receiver())) {
            let flat: Vec<f32> = p.iter().flatten().copied().collect();
            if flat.len() == 3 * self.n * SAMPLES_PER_PATCH {
                fill_buffer(
                    gl,
                    nf.h_points_buffer(),
                    bytes_of(&flat),
                    glow::DYNAMIC_COPY,
                );
                self.h_points = true;
            }
        }
        // SAFETY: a barrier on the current context.
        unsafe { gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT) };
        super::check(gl, "the frame with H from the CPU")?;
        self.last = Some((lights.to_vec(), scales.clone(), true));
        Ok(stats)
    }

    /// The sky of the next frames (`None`: black), as
    /// [`Runtime::set_sky`] sets the CPU's (`rt` the run time this renderer
    /// was made from): refused for a bake without sky visibility, the sky
    /// then unchanged. The next frame runs every pass.
    pub fn set_sky(
        &mut self,
        gl: &glow::Context,
        rt: &Runtime,
        sky: Option<&radiosity_core::sky::Sky>,
    ) -> Result<(), radiosity_runtime::sky::SkyError> {
        if self.sky.sky() == sky {
            return Ok(());
        }
        self.sky.set(gl, rt, sky)?;
        if let Some(p) = &mut self.probes {
            let cells: Option<Vec<[f32; 3]>> = sky.map(|s| {
                s.cell_radiance()
                    .into_iter()
                    .map(|c| c.map(|v| v as f32))
                    .collect()
            });
            p.set_sky(gl, cells.as_deref());
        }
        self.sky_changed = true;
        self.last = None;
        Ok(())
    }

    /// The sky set ([`GlRenderer::set_sky`]).
    pub fn sky(&self) -> Option<&radiosity_core::sky::Sky> {
        self.sky.sky()
    }

    /// Draws `view` from `camera` (`width × height`) with the last frame's
    /// lights and `scales`, into the shading pass's target.
    pub fn draw(
        &mut self,
        gl: &glow::Context,
        camera: &Camera,
        view: View,
        size: (usize, usize),
        scales: &BTreeMap<String, f32>,
    ) -> Result<(), GlError> {
        let materials: Vec<MaterialConstants> = self
            .materials
            .iter()
            .map(|m| {
                let s = scales.get(&m.name).copied().unwrap_or(1.0);
                MaterialConstants {
                    kd: m.kd,
                    albedo: m.albedo,
                    emitted: m.emission.map(|k| s * k / PI),
                }
            })
            .collect();
        // SAFETY: binds of this renderer's buffers on the current context.
        unsafe {
            let b = glow::SHADER_STORAGE_BUFFER;
            gl.bind_buffer_base(b, 6, Some(self.gather.h_buffer()));
            gl.bind_buffer_base(b, 7, Some(self.direct.albedo_buffer()));
            if let Some(nf) = self.near.as_ref().filter(|_| self.h_points) {
                gl.bind_buffer_base(b, 12, Some(nf.h_points_buffer()));
            }
        }
        let binding = self.light_binding();
        let h_points = self.h_points;
        self.shade.mipmaps = self.options.mipmaps;
        self.shade.depth_prepass = self.options.depth_prepass;
        self.timers.begin(gl, Pass::Shade);
        let r = self.shade.draw(
            gl,
            &self.scene,
            &self.map,
            &self.sky,
            &materials,
            camera,
            view,
            size,
            self.n,
            |p| {
                binding.bind(gl, p);
                // SAFETY: a uniform of the current program.
                unsafe {
                    let loc = gl.get_uniform_location(p, "has_h_points");
                    gl.uniform_1_i32(loc.as_ref(), h_points as i32);
                }
            },
        );
        self.timers.end(gl);
        r?;
        if !self.objects.nothing_to_draw() {
            let (w, h) = self.shade.size();
            let vp = super::shade::camera_matrix(camera, w, h, self.scene.lo, self.scene.hi);
            let bvh = self.direct.bvh_buffers();
            let (objects, probes, shade) = (&self.objects, self.probes.as_ref(), &self.shade);
            shade.draw_more(gl, || {
                objects.draw(gl, &vp, view, bvh, probes, |p| binding.bind(gl, p));
            });
            super::check(gl, "drawing the moving objects")?;
        }
        Ok(())
    }

    /// The moving objects' placed triangles ([`radiosity_core::objects`]);
    /// the next frame draws their shadows even when the light is the same.
    pub fn set_objects(
        &mut self,
        gl: &glow::Context,
        vertices: &[radiosity_core::objects::Vertex],
    ) {
        self.objects.set(gl, vertices);
        self.objects_moved = true;
    }

    /// Shows (`true`) or hides the probe view: a sphere of 0.08 of the
    /// probe spacing at each used probe, shaded by its irradiance.
    pub fn set_probe_view(&mut self, gl: &glow::Context, on: bool) {
        let spheres: Vec<(usize, [f64; 3])> = match (&self.probes, on) {
            (Some(p), true) => p.used_positions(),
            _ => Vec::new(),
        };
        let radius = self.probes.as_ref().map_or(0.0, |p| 0.08 * p.grid.spacing);
        self.objects.set_probe_view(gl, &spheres, radius);
    }

    /// The probes' coefficients from the CPU run time
    /// ([`Runtime::probe_sh`]), for frames whose `H` came from it
    /// ([`GlRenderer::frame_with_h`]).
    pub fn set_probe_sh(&self, gl: &glow::Context, sh: &[radiosity_runtime::probes::Sh]) {
        if let Some(p) = &self.probes {
            p.upload(gl, sh);
        }
    }

    /// The probes' coefficients of the last frame read back (none without
    /// probes).
    pub fn probe_sh(&self, gl: &glow::Context) -> Option<Vec<radiosity_runtime::probes::Sh>> {
        self.probes.as_ref().map(|p| p.read(gl))
    }

    /// [`GlRenderer::draw`], then the image read back (blocking).
    pub fn render(
        &mut self,
        gl: &glow::Context,
        camera: &Camera,
        view: View,
        size: (usize, usize),
        scales: &BTreeMap<String, f32>,
    ) -> Result<Image, GlError> {
        self.draw(gl, camera, view, size, scales)?;
        Ok(self.shade.read(gl))
    }

    /// The last drawn image's radiance texture and size.
    pub fn radiance_texture(&self) -> Option<(glow::Texture, (usize, usize))> {
        self.shade.color.map(|t| (t, self.shade.size()))
    }

    /// The last drawn image read back (blocking).
    pub fn read_image(&self, gl: &glow::Context) -> Image {
        self.shade.read(gl)
    }

    /// The latest GPU time of each pass (milliseconds), in [`PASSES`]
    /// order; `wait` blocks until every query issued is done.
    pub fn pass_times(&mut self, gl: &glow::Context, wait: bool) -> [Option<f64>; 4] {
        self.timers.poll(gl, wait);
        self.timers.last
    }

    /// `D`, `B0` and `H` of the last frame read back (blocking; for tests
    /// and reports), three channels of `n`.
    pub fn d(&self, gl: &glow::Context) -> [Vec<f32>; 3] {
        split(read_floats(gl, self.direct.d_buffer(), 3 * self.n), self.n)
    }
    /// `H`'s deviation in each patch's face cells after the last frame (three
    /// channels of `n × 16`; read back), when the renderer has it.
    pub fn h_points(&self, gl: &glow::Context) -> Option<[Vec<f32>; 3]> {
        let nf = self.near.as_ref().filter(|_| self.h_points)?;
        let m = self.n * SAMPLES_PER_PATCH;
        Some(split(read_floats(gl, nf.h_points_buffer(), 3 * m), m))
    }

    /// The near-field correction `c` of the last frame, when the bake has
    /// one (read back).
    pub fn near_field_c(&self, gl: &glow::Context) -> Option<[Vec<f32>; 3]> {
        let nf = self.near.as_ref()?;
        Some(split(read_floats(gl, nf.c_buffer(), 3 * self.n), self.n))
    }
    /// The gather's input `B0 + δ + ρ ∘ c` of the last frame, when the
    /// bake has a near-field correction (read back).
    pub fn near_field_input(&self, gl: &glow::Context) -> Option<[Vec<f32>; 3]> {
        let nf = self.near.as_ref()?;
        Some(split(
            read_floats(gl, nf.gather_input(), 3 * self.n),
            self.n,
        ))
    }
    /// `D` at each lit point of the last frame (three channels of `n ×`
    /// points, patch-major; read back).
    pub fn d_points(&self, gl: &glow::Context) -> ([Vec<f32>; 3], usize) {
        let m = self
            .near
            .as_ref()
            .map_or(self.options.samples, |nf| nf.samples())
            .clamp(1, radiosity_bakefile::surface::SAMPLES_PER_PATCH);
        let all = read_floats(gl, self.direct.d_points_buffer(), 3 * self.n * m);
        (split(all, self.n * m), m)
    }
    pub fn b0(&self, gl: &glow::Context) -> [Vec<f32>; 3] {
        split(read_floats(gl, self.direct.b0_buffer(), 3 * self.n), self.n)
    }
    pub fn h(&self, gl: &glow::Context) -> [Vec<f32>; 3] {
        split(read_floats(gl, self.gather.h_buffer(), 3 * self.n), self.n)
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        self.scene.delete(gl);
        self.map.delete(gl);
        self.shadows.delete(gl);
        self.direct.delete(gl);
        self.gather.delete(gl);
        if let Some(nf) = self.near {
            nf.delete(gl);
        }
        self.shade.delete(gl);
        self.sky.delete(gl);
        if let Some(p) = self.probes {
            p.delete(gl);
        }
        self.objects.delete(gl);
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_buffer(self.lights_buffer);
            gl.delete_buffer(self.views_buffer);
            for q in self
                .timers
                .free
                .into_iter()
                .chain(self.timers.pending.into_iter().flat_map(|p| [p.1, p.2]))
            {
                gl.delete_query(q);
            }
        }
    }
}

fn split(v: Vec<f32>, n: usize) -> [Vec<f32>; 3] {
    std::array::from_fn(|c| v[c * n..(c + 1) * n].to_vec())
}

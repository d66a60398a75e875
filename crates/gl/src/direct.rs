//! Direct light on patches on the GPU (`crates/gl/glsl/direct.comp` with
//! `crates/gl/glsl/light.glsl` and `crates/gl/glsl/shadow_ray.glsl`): `D` at the same sample
//! points as the CPU run time ([`radiosity_runtime::direct`], its reference),
//! shadowed by the same rays — the scene's BVH ([`radiosity_core::bvh`]) on
//! the GPU, traversed in f64 as the CPU traverses it — so that the patch
//! light does not depend on a shadow map's resolution (Sponza's sun at
//! 2048² texels over the scene, 2.2 cm each, missed thin occluders: `D`
//! 16.7 % and the indirect image 3.5 % from the CPU's); `B0 = ρ ∘ D + E`
//! with the run-time emission, and the tile columns of `B0` that the
//! gather must read. Everything stays on the GPU: the gather reads `B0`
//! and the flags from these buffers. (The shading pass's per-pixel direct
//! light keeps the shadow maps.)

use super::{bytes_of, compile_compute, fill_buffer, storage_buffer, GlError};
use glow::HasContext;
use radiosity_bakefile::baked::Baked;
use radiosity_bakefile::codec::TILE;
use radiosity_bakefile::surface::SAMPLES_PER_PATCH;
use radiosity_core::bvh::Bvh;
use radiosity_core::math::{f64s, normalize};
use radiosity_core::scene_config::Light;

pub const SOURCE: &str = include_str!("../glsl/direct.comp");
pub const LIGHT: &str = include_str!("../glsl/light.glsl");
pub const SHADOW_RAY: &str = include_str!("../glsl/shadow_ray.glsl");

/// Storage bindings of the lights and shadow views in light.glsl.
pub const LIGHT_BINDING: usize = 14;
pub const VIEW_BINDING: usize = 15;
/// Storage bindings of shadow_ray.glsl: the BVH's nodes and triangles, and
/// the rays' lift and ends.
pub const BVH_NODE_BINDING: usize = 8;
pub const BVH_TRI_BINDING: usize = 9;
pub const RAY_BINDING: usize = 10;
/// Storage binding of the sky's irradiance at the lit points, added to
/// `D` there for the near-field correction (direct.comp).
const SKY_POINTS_BINDING: usize = 11;

/// The shadow rays' parameters as shadow_ray.glsl reads them (f64): the
/// lift `offset` along the normal, then per light its ray end — for a
/// directional light `far · l` added to the lifted point (`l` the unit
/// direction towards it, as [`radiosity_core::light::Prepared`] normalises
/// it), for a point or spot light its position.
pub fn ray_records(lights: &[Light], offset: f64, far: f64) -> Vec<[f64; 4]> {
    let mut out = vec![[offset, 0.0, 0.0, 0.0]];
    for light in lights {
        out.push(match *light {
            Light::Directional { direction, .. } => {
                let l = normalize(f64s(direction)).map(|c| -c);
                [far * l[0], far * l[1], far * l[2], 0.0]
            }
            Light::Point { position, .. } | Light::Spot { position, .. } => {
                let p = f64s(position);
                [p[0], p[1], p[2], 1.0]
            }
        });
    }
    out
}

/// The direct pass and its buffers.
pub struct GlDirect {
    program: glow::Program,
    /// Sample positions, normals, albedo, emission, `D`, `B0`, tile flags,
    /// `D` at each lit point (bindings 0..=7), the BVH's nodes and
    /// triangles and the rays' records (bindings 8..=10), the sky's
    /// irradiance at the lit points (binding 11).
    pub buffers: [glow::Buffer; 12],
    /// Whether the sky's irradiance at the lit points is added
    /// ([`GlDirect::set_sky_points`]).
    sky_points: bool,
    n: usize,
    tiles: usize,
    /// The shadow rays' lift and length towards directional lights
    /// ([`radiosity_core::direct::DirectLight::offset`] and `far`).
    offset: f64,
    far: f64,
}

impl GlDirect {
    /// Uploads the patches' sample points and albedos, and the scene's BVH
    /// (`bvh`: the CPU run time's, [`radiosity_core::direct::DirectLight::bvh`])
    /// with its shadow rays' `offset` and `far`.
    pub fn new(
        gl: &glow::Context,
        baked: &Baked,
        bvh: &Bvh,
        offset: f64,
        far: f64,
    ) -> Result<GlDirect, GlError> {
        let n = baked.patches.len();
        let program = compile_compute(
            gl,
            "direct.comp",
            &[SHADOW_RAY, LIGHT, SOURCE],
            &[
                ("SAMPLES_PER_PATCH", SAMPLES_PER_PATCH),
                ("TILE", TILE),
                ("LIGHT_BINDING", LIGHT_BINDING),
                ("VIEW_BINDING", VIEW_BINDING),
                ("BVH_NODE_BINDING", BVH_NODE_BINDING),
                ("BVH_TRI_BINDING", BVH_TRI_BINDING),
                ("RAY_BINDING", RAY_BINDING),
                ("SKY_POINTS_BINDING", SKY_POINTS_BINDING),
                ("RAY_SHADOWS", 1),
            ],
        )?;
        let flat = |v: &[[f32; 3]]| v.iter().flatten().copied().collect::<Vec<f32>>();
        let albedo: Vec<f32> = (0..3)
            .flat_map(|c| baked.patches.iter().map(move |p| p.albedo[c]))
            .collect();
        let zeros = vec![0u8; 12 * n];
        let tiles = n.div_ceil(TILE);
        let buffers = [
            storage_buffer(
                gl,
                bytes_of(&flat(&baked.samples.position)),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(
                gl,
                bytes_of(&flat(&baked.samples.normal)),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(gl, bytes_of(&albedo), glow::STATIC_DRAW)?,
            storage_buffer(gl, &zeros, glow::DYNAMIC_DRAW)?,
            storage_buffer(gl, &zeros, glow::DYNAMIC_COPY)?,
            storage_buffer(gl, &zeros, glow::DYNAMIC_COPY)?,
            storage_buffer(gl, &vec![0u8; 4 * tiles], glow::DYNAMIC_COPY)?,
            storage_buffer(
                gl,
                &vec![0u8; 12 * n * SAMPLES_PER_PATCH],
                glow::DYNAMIC_COPY,
            )?,
            // core::bvh's Node (8 words) and Tri (12 words), `repr(C)` as
            // the form-factor kernel reads them too.
            storage_buffer(gl, bytes_of(&bvh.nodes), glow::STATIC_DRAW)?,
            storage_buffer(gl, bytes_of(&bvh.tris), glow::STATIC_DRAW)?,
            storage_buffer(
                gl,
                bytes_of(&ray_records(&[], offset, far)),
                glow::DYNAMIC_DRAW,
            )?,
            storage_buffer(gl, &[0u8; 4], glow::DYNAMIC_DRAW)?,
        ];
        super::check(gl, "uploading the sample points and the scene's BVH")?;
        Ok(GlDirect {
            program,
            buffers,
            sky_points: false,
            n,
            tiles,
            offset,
            far,
        })
    }

    /// The shadow rays of `lights` (the frame's, in the order light.glsl
    /// reads them).
    pub fn set_lights(&self, gl: &glow::Context, lights: &[Light]) {
        let records = ray_records(lights, self.offset, self.far);
        fill_buffer(gl, self.buffers[10], bytes_of(&records), glow::DYNAMIC_DRAW);
    }

    /// The sky's irradiance at the lit points (3 × n × samples, the layout
    /// of [`GlDirect::d_points_buffer`], for the `samples` of the next
    /// dispatches), added to the lights' there; `None`: none.
    pub fn set_sky_points(&mut self, gl: &glow::Context, points: Option<&[f32]>) {
        self.sky_points = points.is_some();
        if let Some(p) = points {
            fill_buffer(gl, self.buffers[11], bytes_of(p), glow::DYNAMIC_DRAW);
        }
    }

    /// Replaces the emission `E` (three channels of `n`).
    pub fn set_emission(&self, gl: &glow::Context, e: &[Vec<f32>; 3]) {
        let flat: Vec<f32> = e.iter().flatten().copied().collect();
        fill_buffer(gl, self.buffers[3], bytes_of(&flat), glow::DYNAMIC_DRAW);
    }

    /// Dispatches `D` and `B0` from the first `samples` points of each
    /// patch, with the lights and views bound by the caller (bindings
    /// [`LIGHT_BINDING`], [`VIEW_BINDING`], the shadow maps on texture
    /// unit 1) and the uniforms of light.glsl set by `set_lights`.
    pub fn dispatch(&self, gl: &glow::Context, samples: usize, set_lights: impl Fn(glow::Program)) {
        // Clear the tile flags: the shader only sets them.
        fill_buffer(
            gl,
            self.buffers[6],
            &vec![0u8; 4 * self.tiles.max(1)],
            glow::DYNAMIC_COPY,
        );
        // SAFETY: binds, uniforms and a dispatch on the current context,
        // buffers sized in `new`.
        unsafe {
            gl.use_program(Some(self.program));
            for (k, b) in self.buffers.iter().enumerate() {
                gl.bind_buffer_base(glow::SHADER_STORAGE_BUFFER, k as u32, Some(*b));
            }
            let loc = |name: &str| gl.get_uniform_location(self.program, name);
            let samples = samples.clamp(1, SAMPLES_PER_PATCH);
            // One invocation per sample point, a power of two a patch
            // (crates/gl/glsl/direct.comp): 64 / lanes patches a work-group.
            let lanes = samples.next_power_of_two();
            gl.uniform_1_u32(loc("n").as_ref(), self.n as u32);
            gl.uniform_1_u32(loc("samples").as_ref(), samples as u32);
            gl.uniform_1_u32(loc("lanes").as_ref(), lanes as u32);
            gl.uniform_1_u32(loc("has_sky_points").as_ref(), self.sky_points as u32);
            set_lights(self.program);
            gl.dispatch_compute(self.n.div_ceil(64 / lanes).max(1) as u32, 1, 1);
        }
    }

    /// Sets every tile flag (a frame without column skipping).
    pub fn activate_all(&self, gl: &glow::Context) {
        // SAFETY: a barrier on the current context before the host write.
        unsafe { gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT) };
        let ones = vec![1u32; self.tiles.max(1)];
        fill_buffer(gl, self.buffers[6], bytes_of(&ones), glow::DYNAMIC_COPY);
    }

    /// The `D` buffer, the `B0` buffer and the tile flags.
    pub fn d_buffer(&self) -> glow::Buffer {
        self.buffers[4]
    }
    pub fn b0_buffer(&self) -> glow::Buffer {
        self.buffers[5]
    }
    pub fn active_buffer(&self) -> glow::Buffer {
        self.buffers[6]
    }
    /// `D` at each lit point (3 × n × samples, channel-major, patch-major
    /// within a channel).
    pub fn d_points_buffer(&self) -> glow::Buffer {
        self.buffers[7]
    }
    /// The scene's BVH nodes and triangles and the shadow-ray records
    /// (shadow_ray.glsl's buffers), for other passes that trace.
    pub fn bvh_buffers(&self) -> [glow::Buffer; 3] {
        [self.buffers[8], self.buffers[9], self.buffers[10]]
    }

    /// The per-patch albedo buffer (3 n, channel-major).
    pub fn albedo_buffer(&self) -> glow::Buffer {
        self.buffers[2]
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_program(self.program);
            for b in self.buffers {
                gl.delete_buffer(b);
            }
        }
    }
}

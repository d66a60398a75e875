//! Direct light on patches on the GPU (`glsl/direct.comp` with
//! `glsl/light.glsl`): `D` from the shadow maps at the same sample points
//! as the CPU run time ([`crate::runtime::direct`], its reference), `B0 = ρ
//! ∘ D + E` with the run-time emission, and the tile columns of `B0` that
//! the gather must read. Everything stays on the GPU: the gather reads
//! `B0` and the flags from these buffers.

use super::{bytes_of, compile_compute, fill_buffer, storage_buffer, GlError};
use crate::bakefile::baked::Baked;
use crate::bakefile::codec::TILE;
use crate::bakefile::surface::SAMPLES_PER_PATCH;
use glow::HasContext;

pub const SOURCE: &str = include_str!("../../glsl/direct.comp");
pub const LIGHT: &str = include_str!("../../glsl/light.glsl");

/// Storage bindings of the lights and shadow views in light.glsl.
pub const LIGHT_BINDING: usize = 14;
pub const VIEW_BINDING: usize = 15;

/// The direct pass and its buffers.
pub struct GlDirect {
    program: glow::Program,
    /// Sample positions, normals, albedo, emission, `D`, `B0`, tile flags,
    /// `D` at each lit point (bindings 0..=7).
    pub buffers: [glow::Buffer; 8],
    n: usize,
    tiles: usize,
}

impl GlDirect {
    /// Uploads the patches' sample points and albedos.
    pub fn new(gl: &glow::Context, baked: &Baked) -> Result<GlDirect, GlError> {
        let n = baked.patches.len();
        let program = compile_compute(
            gl,
            "direct.comp",
            &[LIGHT, SOURCE],
            &[
                ("SAMPLES_PER_PATCH", SAMPLES_PER_PATCH),
                ("TILE", TILE),
                ("LIGHT_BINDING", LIGHT_BINDING),
                ("VIEW_BINDING", VIEW_BINDING),
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
        ];
        super::check(gl, "uploading the sample points")?;
        Ok(GlDirect {
            program,
            buffers,
            n,
            tiles,
        })
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
            // (glsl/direct.comp): 64 / lanes patches a work-group.
            let lanes = samples.next_power_of_two();
            gl.uniform_1_u32(loc("n").as_ref(), self.n as u32);
            gl.uniform_1_u32(loc("samples").as_ref(), samples as u32);
            gl.uniform_1_u32(loc("lanes").as_ref(), lanes as u32);
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

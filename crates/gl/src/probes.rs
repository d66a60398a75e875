//! The probes' update on the GPU (`crates/gl/glsl/probes.comp`; CPU
//! reference: `radiosity_runtime::probes::Decoded::probe`, which
//! tests/gl_probes.rs compares it with) and the buffers the moving objects'
//! lookup reads (`crates/gl/glsl/probe_lookup.glsl`). The entries' weights
//! are decoded once on the host, as the CPU's are, and uploaded; each
//! frame that lit the patches runs one invocation per probe over
//! `B = B0 + ρ∘H` in the renderer's buffers.

use super::{bytes_of, compile_compute, fill_buffer, read_floats, storage_buffer, GlError};
use glow::HasContext;
use radiosity_bakefile::probes::{ProbeGrid, ProbeState};
use radiosity_runtime::probes::{Decoded, Sh};

/// The update's source (without the `#version` line).
pub const SOURCE: &str = include_str!("../glsl/probes.comp");
/// The lookup's source, prepended to object.frag.
pub const LOOKUP: &str = include_str!("../glsl/probe_lookup.glsl");

/// Where the lookup reads the coefficients and the states.
pub const SH_BINDING: usize = 16;
pub const STATE_BINDING: usize = 17;

const LOCAL_SIZE: u32 = 64;

/// The probes on the GPU.
pub struct GlProbes {
    program: glow::Program,
    /// starts, patches, weights, sky starts, sky cells, sky weights, sky
    /// radiance, coefficients, states, emission starts, emitters, emission
    /// weights, the patches' emission, the materials' emitted exitance.
    buffers: [glow::Buffer; 14],
    materials: usize,
    pub grid: ProbeGrid,
    states: Vec<ProbeState>,
    count: usize,
    n: usize,
    has_sky: bool,
}

impl GlProbes {
    /// Uploads `probes` (decoded) for `n` patches.
    pub fn new(
        gl: &glow::Context,
        probes: &Decoded,
        grid: ProbeGrid,
        n: usize,
    ) -> Result<GlProbes, GlError> {
        let program = compile_compute(gl, "probes.comp", &[SOURCE], &[])?;
        let flat = |w: &[[f32; 9]]| w.iter().flatten().copied().collect::<Vec<f32>>();
        let states: Vec<u32> = probes.states.iter().map(|&s| s as u32).collect();
        let count = probes.len();
        // Zero-length buffers are given a word: GL refuses empty storage.
        let nonempty = |b: &[u8]| {
            if b.is_empty() {
                vec![0u8; 4]
            } else {
                b.to_vec()
            }
        };
        let buffers = [
            storage_buffer(gl, &nonempty(bytes_of(&probes.starts)), glow::STATIC_DRAW)?,
            storage_buffer(gl, &nonempty(bytes_of(&probes.patches)), glow::STATIC_DRAW)?,
            storage_buffer(
                gl,
                &nonempty(bytes_of(&flat(&probes.weights))),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(
                gl,
                &nonempty(bytes_of(&probes.sky_starts)),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(
                gl,
                &nonempty(bytes_of(&probes.sky_cells)),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(
                gl,
                &nonempty(bytes_of(&flat(&probes.sky_weights))),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(gl, &[0u8; 4], glow::DYNAMIC_DRAW)?,
            storage_buffer(gl, &vec![0u8; 4 * 27 * count.max(1)], glow::DYNAMIC_COPY)?,
            storage_buffer(gl, &nonempty(bytes_of(&states)), glow::STATIC_DRAW)?,
            storage_buffer(
                gl,
                &nonempty(bytes_of(&probes.emission_starts)),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(gl, &nonempty(bytes_of(&probes.emitters)), glow::STATIC_DRAW)?,
            storage_buffer(
                gl,
                &nonempty(bytes_of(&flat(&probes.emission_weights))),
                glow::STATIC_DRAW,
            )?,
            storage_buffer(gl, &vec![0u8; 12 * n.max(1)], glow::DYNAMIC_DRAW)?,
            storage_buffer(gl, &[0u8; 12], glow::DYNAMIC_DRAW)?,
        ];
        super::check(gl, "uploading the probes")?;
        Ok(GlProbes {
            program,
            buffers,
            grid,
            materials: 0,
            states: probes.states.clone(),
            count,
            n,
            has_sky: false,
        })
    }

    /// The sky's mean radiance per cell the next updates see (`None`:
    /// black).
    pub fn set_sky(&mut self, gl: &glow::Context, cells: Option<&[[f32; 3]]>) {
        self.has_sky = cells.is_some();
        if let Some(c) = cells {
            let flat: Vec<f32> = c.iter().flatten().copied().collect();
            fill_buffer(gl, self.buffers[6], bytes_of(&flat), glow::DYNAMIC_DRAW);
        }
    }

    /// The emission of the next updates: each patch's `E` (3 channels of
    /// `n`) and each material's emitted exitance (`scale × Ke`).
    pub fn set_emission(&mut self, gl: &glow::Context, e: &[Vec<f32>; 3], emitted: &[[f32; 3]]) {
        let flat: Vec<f32> = e.iter().flatten().copied().collect();
        fill_buffer(gl, self.buffers[12], bytes_of(&flat), glow::DYNAMIC_DRAW);
        let m: Vec<f32> = emitted.iter().flatten().copied().collect();
        let m = if m.is_empty() { vec![0.0; 3] } else { m };
        fill_buffer(gl, self.buffers[13], bytes_of(&m), glow::DYNAMIC_DRAW);
        self.materials = emitted.len();
    }

    /// Dispatches the update from the buffers `b0`, `h` and `albedo` (3 n
    /// floats each, channel-major).
    pub fn dispatch(
        &self,
        gl: &glow::Context,
        b0: glow::Buffer,
        h: glow::Buffer,
        albedo: glow::Buffer,
    ) {
        // SAFETY: binds, uniforms and a dispatch on the current context.
        unsafe {
            gl.use_program(Some(self.program));
            let b = glow::SHADER_STORAGE_BUFFER;
            for (k, buf) in self.buffers[..6].iter().enumerate() {
                gl.bind_buffer_base(b, k as u32, Some(*buf));
            }
            gl.bind_buffer_base(b, 6, Some(b0));
            gl.bind_buffer_base(b, 7, Some(h));
            gl.bind_buffer_base(b, 8, Some(albedo));
            gl.bind_buffer_base(b, 9, Some(self.buffers[6]));
            gl.bind_buffer_base(b, 10, Some(self.buffers[7]));
            for k in 0..5 {
                gl.bind_buffer_base(b, 11 + k as u32, Some(self.buffers[9 + k]));
            }
            let loc = |s: &str| gl.get_uniform_location(self.program, s);
            gl.uniform_1_u32(loc("probe_count").as_ref(), self.count as u32);
            gl.uniform_1_u32(loc("n").as_ref(), self.n as u32);
            gl.uniform_1_i32(loc("has_sky").as_ref(), self.has_sky as i32);
            gl.uniform_1_u32(loc("materials").as_ref(), self.materials as u32);
            gl.dispatch_compute((self.count as u32).div_ceil(LOCAL_SIZE).max(1), 1, 1);
            gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT);
        }
    }

    /// Coefficients computed elsewhere (the CPU run time's, for a frame
    /// whose `H` came from it), uploaded.
    pub fn upload(&self, gl: &glow::Context, sh: &[Sh]) {
        if sh.len() != self.count {
            return;
        }
        let flat: Vec<f32> = sh.iter().flatten().flatten().copied().collect();
        fill_buffer(gl, self.buffers[7], bytes_of(&flat), glow::DYNAMIC_COPY);
    }

    /// The coefficients read back (blocking).
    pub fn read(&self, gl: &glow::Context) -> Vec<Sh> {
        let v = read_floats(gl, self.buffers[7], 27 * self.count);
        v.chunks_exact(27)
            .map(|c| std::array::from_fn(|l| std::array::from_fn(|k| c[3 * l + k])))
            .collect()
    }

    /// Binds what the lookup reads for `program`.
    pub fn bind_lookup(&self, gl: &glow::Context, program: glow::Program) {
        // SAFETY: binds and uniforms on the current context.
        unsafe {
            let b = glow::SHADER_STORAGE_BUFFER;
            gl.bind_buffer_base(b, SH_BINDING as u32, Some(self.buffers[7]));
            gl.bind_buffer_base(b, STATE_BINDING as u32, Some(self.buffers[8]));
            let loc = |s: &str| gl.get_uniform_location(program, s);
            let g = &self.grid;
            gl.uniform_3_u32(loc("probe_dims").as_ref(), g.dims[0], g.dims[1], g.dims[2]);
            gl.uniform_3_f32(
                loc("probe_origin").as_ref(),
                g.origin[0],
                g.origin[1],
                g.origin[2],
            );
            gl.uniform_1_f32(loc("probe_spacing").as_ref(), g.spacing);
        }
    }

    /// The used (not solid) probes and their positions.
    pub fn used_positions(&self) -> Vec<(usize, [f64; 3])> {
        self.states
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_used())
            .map(|(p, _)| (p, self.grid.position(p)))
            .collect()
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

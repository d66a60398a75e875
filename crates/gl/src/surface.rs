//! The surface map on the GPU (`crates/gl/glsl/surface.glsl`, evaluated per
//! fragment by the shading pass): the bake file's map
//! ([`radiosity_bakefile::surface::SurfaceMap`]) in five storage buffers,
//! packed to 32-bit words (voxel coordinates are 16-bit; the cuts follow
//! the pieces in their buffer). Its CPU
//! reference is [`radiosity_runtime::surface::weights`].

use super::{bytes_of, storage_buffer, GlError};
use glow::HasContext;
use radiosity_bakefile::surface::SurfaceMap;

/// The map's buffers at bindings 1..=5 and its grid.
pub struct GlSurfaceMap {
    pub buffers: [glow::Buffer; 5],
    pub origin: [f32; 3],
    pub voxel_size: f32,
    pub dims: [u32; 3],
    pub triangles: u32,
    /// Pieces, and cuts after them in the pieces buffer.
    pub pieces: u32,
    pub cuts: u32,
}

impl GlSurfaceMap {
    pub fn new(gl: &glow::Context, map: &SurfaceMap) -> Result<GlSurfaceMap, GlError> {
        let pack = |a: u16, b: u16| a as u32 | (b as u32) << 16;
        // The pieces, then the cuts (5 words each: the positive half's
        // index, the plane's n and d as float bits) in the same buffer: a
        // fragment shader may have as few as 8 storage blocks, and the
        // shading pass uses all 8.
        let mut pieces: Vec<u32> = map
            .pieces
            .iter()
            .flat_map(|p| {
                [
                    pack(p.voxel[0], p.voxel[1]),
                    pack(p.voxel[2], p.flags),
                    p.patch,
                ]
            })
            .collect();
        for (k, c) in &map.cuts {
            pieces.extend([*k, c.n[0].to_bits(), c.n[1].to_bits(), c.n[2].to_bits()]);
            pieces.push(c.d.to_bits());
        }
        if pieces.is_empty() {
            // A storage buffer may not be empty.
            pieces.push(0);
        }
        let voxels: Vec<u32> = map
            .patch_voxel
            .iter()
            .flat_map(|v| [pack(v[0], v[1]), v[2] as u32])
            .collect();
        let directions: Vec<u32> = map.patch_direction.iter().map(|&d| d as u32).collect();
        let neighbours: Vec<u32> = map.neighbours.iter().flatten().copied().collect();
        let s = glow::STATIC_DRAW;
        Ok(GlSurfaceMap {
            buffers: [
                storage_buffer(gl, bytes_of(&map.tri_start), s)?,
                storage_buffer(gl, bytes_of(&pieces), s)?,
                storage_buffer(gl, bytes_of(&voxels), s)?,
                storage_buffer(gl, bytes_of(&directions), s)?,
                storage_buffer(gl, bytes_of(&neighbours), s)?,
            ],
            origin: map.origin.map(|v| v as f32),
            voxel_size: map.voxel_size as f32,
            dims: map.dims,
            triangles: map.triangles() as u32,
            pieces: map.pieces.len() as u32,
            cuts: map.cuts.len() as u32,
        })
    }

    /// Binds the buffers and sets the uniforms of surface.glsl in `program`
    /// (current).
    pub fn bind(&self, gl: &glow::Context, program: glow::Program) {
        // SAFETY: binds and uniforms on the current context.
        unsafe {
            for (k, b) in self.buffers.iter().enumerate() {
                gl.bind_buffer_base(glow::SHADER_STORAGE_BUFFER, 1 + k as u32, Some(*b));
            }
            let loc = |name: &str| gl.get_uniform_location(program, name);
            let o = self.origin;
            gl.uniform_3_f32(loc("map_origin").as_ref(), o[0], o[1], o[2]);
            gl.uniform_1_f32(loc("map_voxel_size").as_ref(), self.voxel_size);
            let d = self.dims;
            gl.uniform_3_u32(loc("map_dims").as_ref(), d[0], d[1], d[2]);
            gl.uniform_1_u32(loc("map_triangles").as_ref(), self.triangles);
            gl.uniform_1_u32(loc("map_pieces").as_ref(), self.pieces);
            gl.uniform_1_u32(loc("map_cuts").as_ref(), self.cuts);
        }
    }

    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            for b in self.buffers {
                gl.delete_buffer(b);
            }
        }
    }
}

//! The gather `H = T̃ · B0` in a compute shader (`glsl/gather.comp`),
//! reading the compressed matrix as it is stored: the BC1 dense part as a
//! compressed texture (`glCompressedTexImage2D`, read with `texelFetch`
//! only) and the exact sparse part from shader storage buffers. Its CPU
//! reference is [`crate::runtime::gather`]; tests/gl_gather.rs compares
//! them.
//!
//! **Layout on the GPU.** The stored tiles (zero tiles are not stored) are
//! placed in a square-ish atlas of `TILE × TILE` texel slots, slot `s` for
//! stored tile `s`; an edge tile (smaller than `TILE`) fills the top-left
//! of its slot. The tile index (first stored tile of each row of tiles,
//! and each stored tile's column) and the sparse part (CSR, three f32
//! values per position) are storage buffers. Per frame the host uploads
//! `B0` and one flag per column of tiles (zero columns of `B0` are not
//! read), dispatches one work-group per row of tiles and reads `H` back.
//!
//! **What decodes differently.** The shader maps each decoded BC1 value
//! through the codec's log scale as a continuous function; the CPU maps
//! `bcdec_rs`'s rounded byte through a table. Where a GPU rounds the
//! interpolated palette entries differently (Mesa's llvmpipe truncates:
//! up to one step of 255 lower, TOOLCHAIN.md), an entry differs by at most
//! a factor `e^{L/255}`: the tests bound `|H_gl − H_cpu|` by
//! `(e^{L/255} − 1) H_cpu` plus f32 rounding.
//!
//! Every codec variant of the file: BC1 (the thesis's codec, three
//! channels in one RGB texture), BC4 (one red texture layer per stored
//! channel; a grey matrix's one layer serves the three channels of `B0`),
//! BC6H (a BPTC half-float texture, values times the stored power of two's
//! inverse) and the plain f16 and f32 tiles (read from a storage buffer as
//! stored).

use super::{bytes_of, compile_compute, GlError};
use crate::bakefile::codec::{DenseFormat, Encoded, TILE};
use crate::runtime::gather::ActiveColumns;
use glow::HasContext;

/// The shader's source (without the `#version` line).
pub const SOURCE: &str = include_str!("../../glsl/gather.comp");

/// A compressed matrix on the GPU, ready to gather.
pub struct GlGather {
    program: glow::Program,
    atlas: glow::Texture,
    /// Storage buffers at bindings 0..=10 (row starts, tile columns, B0,
    /// active tile columns, sparse rows, sparse columns, sparse values, H,
    /// the plain formats' dense bytes, stored tiles' byte offsets, the
    /// matrix's column scales: ones where it has none).
    buffers: [glow::Buffer; 11],
    n: usize,
    tiles_per_side: usize,
    atlas_tiles_x: usize,
    scale: [f32; 3],
    log_range: f32,
    /// Texture layers (BC4: one per stored channel), the format as the
    /// shader numbers it (0 BC1, 1 BC4, 2 BC6H, 3 f16, 4 f32), stored
    /// channels and the dense image's side.
    layers: usize,
    format: u32,
    channels: usize,
    image_size: usize,
    /// Bytes of the compressed matrix on the GPU (atlas padding excluded).
    pub bytes: u64,
}

impl GlGather {
    /// Uploads `e`. The context must be current.
    pub fn new(gl: &glow::Context, e: &Encoded) -> Result<GlGather, GlError> {
        // The texture of the block formats: BC1 one RGB layer, BC4 one red
        // layer per stored channel, BC6H one RGB half-float layer; the plain
        // formats are read from a storage buffer (a 1-tile dummy texture).
        let (layers, internal, block_bytes) = match e.format {
            DenseFormat::Bc1 => (1, glow::COMPRESSED_RGB_S3TC_DXT1_EXT, 8),
            DenseFormat::Bc4 => (e.channels, glow::COMPRESSED_RED_RGTC1, 8),
            DenseFormat::Bc6h => (1, glow::COMPRESSED_RGB_BPTC_UNSIGNED_FLOAT, 16),
            DenseFormat::F16 | DenseFormat::F32 => (1, glow::COMPRESSED_RGB_S3TC_DXT1_EXT, 8),
        };
        let plain = matches!(e.format, DenseFormat::F16 | DenseFormat::F32);
        if e.format == DenseFormat::Bc1 && e.channels != 3 {
            return Err(GlError::Unsupported(format!(
                "a BC1 matrix of {} channel(s) (codec {})",
                e.channels,
                e.kind.name()
            )));
        }
        let tile = e.index.tile;
        assert_eq!(tile, TILE, "the codec's tile edge");
        let stored = if plain { 1 } else { e.index.cols.len() };
        // SAFETY: queries and object creation on the current context.
        let max_texture = unsafe { gl.get_parameter_i32(glow::MAX_TEXTURE_SIZE) }.max(0) as usize;
        let per_side = max_texture / tile;
        let ax = ((stored as f64).sqrt().ceil() as usize).clamp(1, per_side.max(1));
        let ay = stored.div_ceil(ax).max(1);
        if ay > per_side {
            return Err(GlError::Unsupported(format!(
                "{stored} stored tiles need an atlas of {ax} x {ay} tiles of {tile} texels; \
                 this GL allows textures of {max_texture} texels"
            )));
        }
        let (w, h) = (ax * tile, ay * tile);
        let row_blocks = w / 4;
        let layer_bytes = (w / 4) * (h / 4) * block_bytes;
        let mut atlas = vec![0u8; layers * layer_bytes];
        let mut slot = 0usize;
        for tr in 0..if plain { 0 } else { e.index.tiles_per_side } {
            let th = tile.min(e.image_size - tr * tile);
            for k in e.index.row_start[tr] as usize..e.index.row_start[tr + 1] as usize {
                let tw = tile.min(e.image_size - e.index.cols[k] as usize * tile);
                let (bh, bw) = (th / 4, tw / 4);
                let src = &e.dense[e.index.offsets[k] as usize..];
                let (sx, sy) = (slot % ax, slot / ax);
                // A BC4 tile holds its channels as planes of blocks.
                for layer in 0..layers {
                    for br in 0..bh {
                        for bc in 0..bw {
                            let bb = block_bytes;
                            let from = layer * bh * bw * bb + bb * (br * bw + bc);
                            let to = layer * layer_bytes
                                + bb * ((sy * tile / 4 + br) * row_blocks + sx * tile / 4 + bc);
                            atlas[to..to + bb].copy_from_slice(&src[from..from + bb]);
                        }
                    }
                }
                slot += 1;
            }
        }
        let program = compile_compute(gl, "gather.comp", &[SOURCE], &[("TILE", tile)])?;
        // SAFETY: object creation and uploads on the current context, with
        // sizes matching the data.
        unsafe {
            let texture = gl.create_texture().map_err(GlError::Call)?;
            gl.bind_texture(glow::TEXTURE_2D_ARRAY, Some(texture));
            gl.compressed_tex_image_3d(
                glow::TEXTURE_2D_ARRAY,
                0,
                internal as i32,
                w as i32,
                h as i32,
                layers as i32,
                0,
                atlas.len() as i32,
                &atlas,
            );
            // texelFetch ignores filtering; NEAREST and one level make the
            // texture complete.
            let t = glow::TEXTURE_2D_ARRAY;
            gl.tex_parameter_i32(t, glow::TEXTURE_MIN_FILTER, glow::NEAREST as i32);
            gl.tex_parameter_i32(t, glow::TEXTURE_MAG_FILTER, glow::NEAREST as i32);
            gl.tex_parameter_i32(t, glow::TEXTURE_MAX_LEVEL, 0);
            let mut buffers = Vec::with_capacity(11);
            for _ in 0..11 {
                buffers.push(gl.create_buffer().map_err(GlError::Call)?);
            }
            let buffers: [glow::Buffer; 11] = buffers.try_into().expect("eleven buffers");
            let upload = |b: glow::Buffer, data: &[u8]| {
                gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(b));
                // At least 4 bytes: an empty buffer cannot be bound.
                let data = if data.is_empty() { &[0u8; 4][..] } else { data };
                gl.buffer_data_u8_slice(glow::SHADER_STORAGE_BUFFER, data, glow::STATIC_DRAW);
            };
            upload(buffers[0], bytes_of(&e.index.row_start));
            let cols: Vec<u32> = e.index.cols.iter().map(|&c| c as u32).collect();
            upload(buffers[1], bytes_of(&cols));
            let sp = &e.sparse;
            let row_ptr: Vec<u32> = if sp.is_empty() {
                vec![0; e.n + 1]
            } else {
                sp.row_ptr.clone()
            };
            upload(buffers[4], bytes_of(&row_ptr));
            upload(buffers[5], bytes_of(&sp.cols));
            // Three values per position (a grey matrix's one repeated).
            let values: Vec<f32> = if e.channels == 3 {
                sp.values.clone()
            } else {
                sp.values.iter().flat_map(|&v| [v; 3]).collect()
            };
            upload(buffers[6], bytes_of(&values));
            // The plain formats' tiles as they are stored, and each stored
            // tile's byte offset (little-endian words, as on every GPU).
            if plain {
                let mut words = e.dense.clone();
                words.resize(e.dense.len().div_ceil(4) * 4, 0);
                upload(buffers[8], &words);
            } else {
                upload(buffers[8], &[]);
            }
            upload(buffers[9], bytes_of(&e.index.offsets));
            let col_scale = if e.col_scale.is_empty() {
                vec![1.0f32; e.n]
            } else {
                e.col_scale.clone()
            };
            upload(buffers[10], bytes_of(&col_scale));
            gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(buffers[7]));
            gl.buffer_data_size(
                glow::SHADER_STORAGE_BUFFER,
                (12 * e.n.max(1)) as i32,
                glow::DYNAMIC_COPY,
            );
            if let Some(code) = Some(gl.get_error()).filter(|&c| c != glow::NO_ERROR) {
                return Err(GlError::Call(format!(
                    "uploading the matrix: GL error 0x{code:x}"
                )));
            }
            Ok(GlGather {
                program,
                atlas: texture,
                buffers,
                n: e.n,
                tiles_per_side: e.index.tiles_per_side,
                atlas_tiles_x: ax,
                scale: std::array::from_fn(|c| e.scale[c.min(e.channels - 1)]),
                log_range: e.log_range,
                layers,
                format: match e.format {
                    DenseFormat::Bc1 => 0,
                    DenseFormat::Bc4 => 1,
                    DenseFormat::Bc6h => 2,
                    DenseFormat::F16 => 3,
                    DenseFormat::F32 => 4,
                },
                channels: e.channels,
                image_size: e.image_size,
                bytes: (e.dense.len()
                    + 4 * (row_ptr.len()
                        + cols.len()
                        + sp.cols.len()
                        + sp.values.len()
                        + e.col_scale.len())) as u64,
            })
        }
    }

    /// `H = T̃ · B0` over the `active` columns (per tile column: a tile
    /// column with no active group is not read), three channels of `n`.
    pub fn gather(
        &self,
        gl: &glow::Context,
        b0: [&[f32]; 3],
        active: &ActiveColumns,
    ) -> Result<[Vec<f32>; 3], GlError> {
        let n = self.n;
        let mut flat = Vec::with_capacity(3 * n);
        for c in b0 {
            assert_eq!(c.len(), n, "B0 must have one value per patch");
            flat.extend_from_slice(c);
        }
        let tile_active: Vec<u32> = active.mask.iter().map(|&m| u32::from(m != 0)).collect();
        let mut out = vec![0u8; 12 * n];
        // SAFETY: uploads, a dispatch and a read-back on the current
        // context, buffers sized to the data.
        unsafe {
            gl.use_program(Some(self.program));
            gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(self.buffers[2]));
            gl.buffer_data_u8_slice(
                glow::SHADER_STORAGE_BUFFER,
                bytes_of(&flat),
                glow::DYNAMIC_DRAW,
            );
            gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(self.buffers[3]));
            gl.buffer_data_u8_slice(
                glow::SHADER_STORAGE_BUFFER,
                bytes_of(&tile_active),
                glow::DYNAMIC_DRAW,
            );
            self.dispatch(gl, self.buffers[2], self.buffers[3]);
            gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT | glow::BUFFER_UPDATE_BARRIER_BIT);
            gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(self.buffers[7]));
            gl.get_buffer_sub_data(glow::SHADER_STORAGE_BUFFER, 0, &mut out);
            let code = gl.get_error();
            if code != glow::NO_ERROR {
                return Err(GlError::Call(format!("the gather: GL error 0x{code:x}")));
            }
        }
        let v: Vec<f32> = out
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        Ok(std::array::from_fn(|c| v[c * n..(c + 1) * n].to_vec()))
    }

    /// Dispatches the gather of the `B0` in storage buffer `b0` (3 n
    /// floats, channel-major) over the tile columns flagged in
    /// `tile_active` (one u32 per tile column), into [`GlGather::h_buffer`];
    /// nothing is read back. The caller orders later reads with a barrier.
    pub fn dispatch(&self, gl: &glow::Context, b0: glow::Buffer, tile_active: glow::Buffer) {
        // SAFETY: binds, uniforms and a dispatch on the current context;
        // the buffers are sized by `new` and the caller.
        unsafe {
            gl.use_program(Some(self.program));
            for (k, b) in self.buffers.iter().enumerate() {
                let b = match k {
                    2 => b0,
                    3 => tile_active,
                    _ => *b,
                };
                gl.bind_buffer_base(glow::SHADER_STORAGE_BUFFER, k as u32, Some(b));
            }
            gl.active_texture(glow::TEXTURE0);
            gl.bind_texture(glow::TEXTURE_2D_ARRAY, Some(self.atlas));
            let loc = |name: &str| gl.get_uniform_location(self.program, name);
            gl.uniform_1_i32(loc("atlas").as_ref(), 0);
            gl.uniform_1_u32(loc("n").as_ref(), self.n as u32);
            gl.uniform_1_u32(loc("atlas_tiles_x").as_ref(), self.atlas_tiles_x as u32);
            gl.uniform_3_f32(
                loc("scale").as_ref(),
                self.scale[0],
                self.scale[1],
                self.scale[2],
            );
            gl.uniform_1_f32(loc("log_range").as_ref(), self.log_range);
            gl.uniform_1_u32(loc("format").as_ref(), self.format);
            gl.uniform_1_u32(loc("layers").as_ref(), self.layers as u32);
            gl.uniform_1_u32(loc("channels").as_ref(), self.channels as u32);
            gl.uniform_1_u32(loc("image_size").as_ref(), self.image_size as u32);
            gl.dispatch_compute(self.tiles_per_side as u32, 1, 1);
        }
    }

    /// The storage buffer `H` is written to (3 n floats, channel-major).
    pub fn h_buffer(&self) -> glow::Buffer {
        self.buffers[7]
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: the objects were created on this context and are not
        // used after.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_texture(self.atlas);
            for b in self.buffers {
                gl.delete_buffer(b);
            }
        }
    }
}

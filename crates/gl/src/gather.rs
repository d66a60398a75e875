//! The gather `H = T̃ · B0` on the GPU: three compute passes of
//! `crates/gl/glsl/gather.comp` over the compressed matrix as it is stored, decoded
//! in the shader with the CPU decoder's integer arithmetic and tables. Its
//! CPU reference is [`radiosity_runtime::gather`]; tests/gl_gather.rs compares
//! them.
//!
//! **Exact on every vendor.** No texture unit decodes an entry: BC1's
//! palette bytes are computed as `bcdec_rs` computes them
//! ([`radiosity_runtime::gather`]'s palette) and mapped through the codec's
//! 256-entry log table (held in shared memory); BC4 through the CPU's
//! tables by interpolation numerator ([`radiosity_runtime::gather::bc4_levels`]);
//! BC6H from blocks unpacked at upload as the CPU unpacks them
//! ([`radiosity_runtime::gather::unpack_bc6h_block`]); f16, f32 and the sparse
//! part's RGB9E5, f16 and f32 values bit for bit. GL and CPU then multiply
//! the same f32 entries by the same f32 inputs and differ only in the order
//! of their f32 sums: per row at most `γ_m Σ_j |T̃_ij x_j|` each from the
//! exact sum (`m` terms, `γ_m = m u / (1 − m u)`, `u = 2⁻²⁴`; Higham,
//! *Accuracy and Stability of Numerical Algorithms*, 2nd ed., eq. 3.5), so
//! twice that apart. Texture units were not: Mesa's llvmpipe truncates BC1's
//! interpolated bytes, and NVIDIA's H200 decoded entries ~3 log-byte steps
//! (3.6 %) from the CPU's.
//!
//! **Parallel.** Per frame ([`GlGather::dispatch`]):
//! 0. one work-group per row of tiles: the input `x = s ∘ B0` of one tile
//!    column (column scales folded in, zero past `n`), and the row's stored
//!    tiles in active tile columns compacted into a list (a work-group
//!    prefix sum over the row's tile index, in stored order): zero tiles and
//!    inactive columns are never visited again this frame;
//! 1. one work-group of 256 invocations per row of tiles and slab of
//!    [`SLAB`] listed tiles: each group of 32 invocations decodes one tile
//!    at a time, two 4 × 4 blocks an invocation, and keeps its blocks' rows
//!    in registers over the slab; the work-group sums them in shared memory
//!    in a fixed order into the slab's partial rows;
//! 2. one group of 32 invocations per row: the row's sparse entries strided
//!    over the 32, summed in a fixed tree, plus its slabs' partial rows in
//!    slab order, written to `H`.
//!
//! Every sum has a fixed order given the frame's active tile columns, so
//! the result is deterministic; skipping columns changes only the order of
//! the dense sums (the tests bound it as above). The sparse part is read
//! whole every frame (its bytes are counted by [`GlGather::bytes_read`]).
//!
//! **Layout on the GPU.** The dense tiles as the file stores them (BC6H:
//! unpacked, 44 bytes a block, as the CPU gather holds them), the tile
//! index (row starts, tile columns as u32, byte offsets), the sparse part
//! as the file's precision holds it (u16 columns two to a word; RGB9E5
//! words, or f16 halves, or f32 values), the decoders' tables, and the
//! frame's buffers (`x`, the list, per-row counts, slab partials, `H`).

use super::{bytes_of, compile_compute, storage_buffer, GlError};
use glow::HasContext;
use radiosity_bakefile::codec::{DenseFormat, Encoded, SparseValues, TILE};
use radiosity_runtime::gather::{
    bc4_levels, rgb9e5_factors, unpack_bc6h_block, ActiveColumns, BC6H_UNPACKED_BYTES,
};

/// The shader's source (without the `#version` line).
pub const SOURCE: &str = include_str!("../glsl/gather.comp");

/// Listed tiles a work-group of the tile pass takes (four per group of 32
/// invocations): small enough that a row of tiles spreads over several
/// work-groups (403 rows × 13 slabs at 12,872 patches, every column), large
/// enough that a work-group's fixed cost (its shared-memory sum of 32 rows)
/// stays a small part of its 16 KiB of BC1.
pub const SLAB: usize = 32;

/// Rows a work-group of the reduction pass takes (32 invocations a row;
/// `WARPS` in the shader).
const ROWS_PER_GROUP: usize = 8;

/// The shader's format numbers (`FORMAT`).
fn format_number(f: DenseFormat) -> usize {
    match f {
        DenseFormat::Bc1 => 0,
        DenseFormat::Bc4 => 1,
        DenseFormat::Bc6h => 2,
        DenseFormat::F16 => 3,
        DenseFormat::F32 => 4,
    }
}

/// Storage buffer bindings of `crates/gl/glsl/gather.comp`.
mod binding {
    pub const ROW_START: u32 = 0;
    pub const TILE_COL: u32 = 1;
    pub const B0: u32 = 2;
    pub const ACTIVE: u32 = 3;
    pub const SPARSE_ROW: u32 = 4;
    pub const SPARSE_COL: u32 = 5;
    pub const SPARSE_VAL: u32 = 6;
    pub const H: u32 = 7;
    pub const DENSE: u32 = 8;
    pub const OFFSET: u32 = 9;
    pub const COL_SCALE: u32 = 10;
    pub const X: u32 = 11;
    pub const LIST: u32 = 12;
    pub const COUNT: u32 = 13;
    pub const PARTIAL: u32 = 14;
    pub const TABLE: u32 = 15;
}

/// The GPU buffers of one matrix.
struct Buffers {
    row_start: glow::Buffer,
    tile_col: glow::Buffer,
    sparse_row: glow::Buffer,
    sparse_col: glow::Buffer,
    sparse_val: glow::Buffer,
    dense: glow::Buffer,
    offset: glow::Buffer,
    col_scale: glow::Buffer,
    dense_table: glow::Buffer,
    sparse_table: glow::Buffer,
    /// Per frame: the input `s ∘ B0`, the list of active stored tiles, its
    /// count per row, the slabs' partial rows, `H`.
    x: glow::Buffer,
    list: glow::Buffer,
    count: glow::Buffer,
    partial: glow::Buffer,
    h: glow::Buffer,
    /// [`GlGather::gather`]'s own `B0` and tile-column flags.
    b0: glow::Buffer,
    active: glow::Buffer,
}

impl Buffers {
    fn all(&self) -> [glow::Buffer; 17] {
        [
            self.row_start,
            self.tile_col,
            self.sparse_row,
            self.sparse_col,
            self.sparse_val,
            self.dense,
            self.offset,
            self.col_scale,
            self.dense_table,
            self.sparse_table,
            self.x,
            self.list,
            self.count,
            self.partial,
            self.h,
            self.b0,
            self.active,
        ]
    }
}

/// A compressed matrix on the GPU, ready to gather.
pub struct GlGather {
    /// The three passes (compact, tiles, reduce).
    programs: [glow::Program; 3],
    buffers: Buffers,
    n: usize,
    tiles_per_side: usize,
    /// Work-groups of the tile pass per row of tiles: the most stored
    /// tiles of a row, in slabs.
    slabs: usize,
    /// Host copies for [`GlGather::bytes_read`]: each stored tile's tile
    /// column and bytes on the GPU.
    tile_cols: Vec<u16>,
    tile_bytes: Vec<u32>,
    /// Bytes read every frame whatever is active: the tile index and the
    /// sparse part.
    bytes_fixed: u64,
    /// Bytes of the compressed matrix on the GPU.
    pub bytes: u64,
}

/// The dense part as the GPU reads it, with each stored tile's byte offset.
fn dense_words(e: &Encoded) -> (Vec<u8>, Vec<u32>) {
    if e.format != DenseFormat::Bc6h {
        let mut bytes = e.dense.clone();
        bytes.resize(e.dense.len().div_ceil(4) * 4, 0);
        return (bytes, e.index.offsets.clone());
    }
    // BC6H: every block unpacked, tiles in stored order.
    let tile = e.index.tile;
    let mut out = Vec::with_capacity(e.dense.len() / 16 * BC6H_UNPACKED_BYTES);
    let mut offsets = Vec::with_capacity(e.index.offsets.len());
    for tr in 0..e.index.tiles_per_side {
        let h = tile.min(e.image_size - tr * tile);
        for slot in e.index.row_start[tr] as usize..e.index.row_start[tr + 1] as usize {
            let w = tile.min(e.image_size - e.index.cols[slot] as usize * tile);
            let start = e.index.offsets[slot] as usize;
            offsets.push(out.len() as u32);
            for k in 0..(h / 4) * (w / 4) {
                let b = start + 16 * k;
                unpack_bc6h_block(e.dense[b..b + 16].try_into().expect("16 bytes"), &mut out);
            }
        }
    }
    (out, offsets)
}

/// The sparse values as the GPU reads them, and the precision the shader
/// decodes (`SPARSE`: 0 f32, 1 f16, 2 RGB9E5) with its table. Each value
/// is re-packed from the f32 the decoder holds and checked to unpack to
/// the same bits; a part that does not (none the encoder writes) goes up
/// as f32.
fn sparse_words(e: &Encoded) -> (Vec<u32>, usize, Vec<f32>) {
    let sp = &e.sparse;
    let ch = e.channels;
    let as_f32 = || {
        (
            sp.values.iter().map(|v| v.to_bits()).collect(),
            0,
            vec![0.0],
        )
    };
    match sp.precision {
        SparseValues::Rgb9e5 if ch == 3 => {
            let factors = rgb9e5_factors(sp.scale);
            let mut words = Vec::with_capacity(sp.len());
            for v in sp.values.chunks_exact(3) {
                let w = radiosity_bakefile::codec::rgb9e5::pack(std::array::from_fn(|c| {
                    v[c] * sp.scale[c]
                }));
                let f = &factors[(w >> 27) as usize];
                let back: [f32; 3] = std::array::from_fn(|c| ((w >> (9 * c)) & 511) as f32 * f[c]);
                if back != [v[0], v[1], v[2]] {
                    return as_f32();
                }
                words.push(w);
            }
            let table = factors.iter().flat_map(|f| [f[0], f[1], f[2]]).collect();
            (words, 2, table)
        }
        // f16, and a grey part asked for RGB9E5 (one channel has nothing to
        // share: the encoder stores it as f16).
        SparseValues::F16 | SparseValues::Rgb9e5 => {
            let inv: [f32; 3] = std::array::from_fn(|c| 1.0 / sp.scale[c.min(ch - 1)]);
            let mut halves = Vec::with_capacity(sp.values.len());
            for (k, &v) in sp.values.iter().enumerate() {
                let c = k % ch;
                let hb = half::f16::from_f32(v * sp.scale[c]).to_bits();
                if half::f16::from_bits(hb).to_f32() * inv[c] != v {
                    return as_f32();
                }
                halves.push(hb);
            }
            let words = halves
                .chunks(2)
                .map(|p| u32::from(p[0]) | u32::from(*p.get(1).unwrap_or(&0)) << 16)
                .collect();
            (words, 1, inv.to_vec())
        }
        _ => as_f32(),
    }
}

/// The dense decoder's table (`Table` in pass 1): BC1 the log byte values
/// of the three channels (3 × 256), BC4 per stored channel its levels by
/// numerator (1786 + 1276), f16 and BC6H the inverse scales.
fn dense_table(e: &Encoded) -> Vec<f32> {
    let book = e.codebook();
    match e.format {
        DenseFormat::Bc1 => book.lut.iter().flatten().copied().collect(),
        DenseFormat::Bc4 => (0..e.channels)
            .flat_map(|c| {
                let (t7, t5) = bc4_levels(e.scale[c], e.log_range);
                t7.into_iter().chain(t5)
            })
            .collect(),
        DenseFormat::Bc6h | DenseFormat::F16 => (0..3)
            .map(|c| book.inv_scale[c.min(e.channels - 1)])
            .collect(),
        DenseFormat::F32 => vec![0.0],
    }
}

impl GlGather {
    /// Uploads `e`. The context must be current.
    pub fn new(gl: &glow::Context, e: &Encoded) -> Result<GlGather, GlError> {
        let tile = e.index.tile;
        if tile != TILE {
            return Err(GlError::Unsupported(format!(
                "a matrix of {tile}-texel tiles (the GL gather decodes {TILE})"
            )));
        }
        if e.n > 1 << 16 {
            return Err(GlError::Unsupported(format!(
                "a matrix of {} patches (the GL gather's sparse columns are 16-bit)",
                e.n
            )));
        }
        let tps = e.index.tiles_per_side;
        let padded = tps * tile;
        let (dense, offsets) = dense_words(e);
        let (sparse_val, sparse_code, sparse_table) = sparse_words(e);
        let sp = &e.sparse;
        let row_ptr: Vec<u32> = if sp.is_empty() {
            vec![0; e.n + 1]
        } else {
            sp.row_ptr.clone()
        };
        let sparse_col: Vec<u32> = sp
            .cols
            .chunks(2)
            .map(|p| p[0] | p.get(1).copied().unwrap_or(0) << 16)
            .collect();
        let tile_col: Vec<u32> = e.index.cols.iter().map(|&c| u32::from(c)).collect();
        let most = (0..tps)
            .map(|tr| (e.index.row_start[tr + 1] - e.index.row_start[tr]) as usize)
            .max()
            .unwrap_or(0);
        let slabs = most.div_ceil(SLAB).max(1);
        let col_scale = if e.col_scale.is_empty() {
            vec![1.0f32; e.n]
        } else {
            e.col_scale.clone()
        };
        // The largest buffers against what this GL allows one block.
        // SAFETY: a query on the current context.
        let max_block = unsafe { gl.get_parameter_i64(glow::MAX_SHADER_STORAGE_BLOCK_SIZE) };
        let partial_bytes = 16 * slabs * padded;
        for (what, bytes) in [
            ("the dense tiles", dense.len()),
            ("the sparse values", 4 * sparse_val.len()),
            ("the slabs' partial rows", partial_bytes),
        ] {
            if bytes as i64 > max_block {
                return Err(GlError::Unsupported(format!(
                    "{what} take {bytes} bytes; this GL allows a storage block of {max_block}"
                )));
            }
        }
        let mut tile_bytes = vec![0u32; e.index.cols.len()];
        for tr in 0..tps {
            let h = tile.min(e.image_size - tr * tile);
            for (slot, b) in tile_bytes
                .iter_mut()
                .enumerate()
                .take(e.index.row_start[tr + 1] as usize)
                .skip(e.index.row_start[tr] as usize)
            {
                let w = tile.min(e.image_size - e.index.cols[slot] as usize * tile);
                *b = if e.format == DenseFormat::Bc6h {
                    ((h / 4) * (w / 4) * BC6H_UNPACKED_BYTES) as u32
                } else {
                    e.format.tile_bytes(h, w, e.channels) as u32
                };
            }
        }
        let defines = |pass: usize| {
            [
                ("TILE", tile),
                ("PASS", pass),
                ("FORMAT", format_number(e.format)),
                ("CHANNELS", e.channels),
                ("SPARSE", sparse_code),
                (
                    "SPARSE_CHANNELS",
                    if sparse_code == 2 { 3 } else { e.channels },
                ),
            ]
        };
        let mut programs = Vec::with_capacity(3);
        for pass in 0..3 {
            match compile_compute(gl, "gather.comp", &[SOURCE], &defines(pass)) {
                Ok(p) => programs.push(p),
                Err(err) => {
                    // SAFETY: programs of this context, not used after.
                    unsafe { programs.iter().for_each(|&p| gl.delete_program(p)) };
                    return Err(err);
                }
            }
        }
        let programs: [glow::Program; 3] = programs.try_into().expect("three passes");
        let dynamic = |bytes: usize| storage_buffer(gl, &vec![0u8; bytes], glow::DYNAMIC_COPY);
        let buffers = Buffers {
            row_start: storage_buffer(gl, bytes_of(&e.index.row_start), glow::STATIC_DRAW)?,
            tile_col: storage_buffer(gl, bytes_of(&tile_col), glow::STATIC_DRAW)?,
            sparse_row: storage_buffer(gl, bytes_of(&row_ptr), glow::STATIC_DRAW)?,
            sparse_col: storage_buffer(gl, bytes_of(&sparse_col), glow::STATIC_DRAW)?,
            sparse_val: storage_buffer(gl, bytes_of(&sparse_val), glow::STATIC_DRAW)?,
            dense: storage_buffer(gl, &dense, glow::STATIC_DRAW)?,
            offset: storage_buffer(gl, bytes_of(&offsets), glow::STATIC_DRAW)?,
            col_scale: storage_buffer(gl, bytes_of(&col_scale), glow::STATIC_DRAW)?,
            dense_table: storage_buffer(gl, bytes_of(&dense_table(e)), glow::STATIC_DRAW)?,
            sparse_table: storage_buffer(gl, bytes_of(&sparse_table), glow::STATIC_DRAW)?,
            x: dynamic(16 * padded)?,
            list: dynamic(4 * e.index.cols.len())?,
            count: dynamic(4 * tps)?,
            partial: dynamic(partial_bytes)?,
            h: dynamic(12 * e.n.max(1))?,
            b0: dynamic(12 * e.n.max(1))?,
            active: dynamic(4 * tps)?,
        };
        // The uniforms do not change: set once per program.
        // SAFETY: uniforms of this context's programs.
        unsafe {
            for &p in &programs {
                gl.use_program(Some(p));
                let loc = |name: &str| gl.get_uniform_location(p, name);
                gl.uniform_1_u32(loc("n").as_ref(), e.n as u32);
                gl.uniform_1_u32(loc("image_size").as_ref(), e.image_size as u32);
                gl.uniform_1_u32(loc("tiles_per_side").as_ref(), tps as u32);
                gl.uniform_1_u32(loc("padded").as_ref(), padded as u32);
                gl.uniform_1_u32(loc("slab").as_ref(), SLAB as u32);
            }
            gl.use_program(None);
        }
        let g = GlGather {
            programs,
            n: e.n,
            tiles_per_side: tps,
            slabs,
            tile_cols: e.index.cols.clone(),
            tile_bytes,
            bytes_fixed: 4 * (e.index.row_start.len() + 2 * e.index.cols.len()) as u64
                + 4 * (row_ptr.len() + sparse_col.len() + sparse_val.len() + e.n) as u64,
            bytes: (dense.len()
                + 4 * (e.index.row_start.len()
                    + 2 * tile_col.len()
                    + row_ptr.len()
                    + sparse_col.len()
                    + sparse_val.len()
                    + col_scale.len())) as u64,
            buffers,
        };
        if let Err(err) = super::check(gl, "uploading the matrix") {
            g.delete(gl);
            return Err(err);
        }
        Ok(g)
    }

    /// Bytes a product over `active`'s tile columns reads from the
    /// compressed matrix: the dense tiles in active tile columns, the tile
    /// index, the sparse part whole and the column scales (the frame's own
    /// buffers — `B0`, `x`, the list, the partial rows, `H` — not counted).
    pub fn bytes_read(&self, active: &ActiveColumns) -> u64 {
        let dense: u64 = self
            .tile_cols
            .iter()
            .zip(&self.tile_bytes)
            .filter(|(&c, _)| active.mask.get(c as usize).is_some_and(|&m| m != 0))
            .map(|(_, &b)| u64::from(b))
            .sum();
        dense + self.bytes_fixed
    }

    /// Uploads `B0` (three channels of `n`) and `active`'s tile-column
    /// flags into this gather's own input buffers, for [`GlGather::run`].
    pub fn set_input(&self, gl: &glow::Context, b0: [&[f32]; 3], active: &ActiveColumns) {
        let n = self.n;
        let mut flat = Vec::with_capacity(3 * n);
        for c in b0 {
            assert_eq!(c.len(), n, "B0 must have one value per patch");
            flat.extend_from_slice(c);
        }
        let flags: Vec<u32> = (0..self.tiles_per_side)
            .map(|t| u32::from(active.mask.get(t).is_some_and(|&m| m != 0)))
            .collect();
        // SAFETY: uploads into buffers sized for them in `new`.
        unsafe {
            for (b, data) in [
                (self.buffers.b0, bytes_of(&flat)),
                (self.buffers.active, bytes_of(&flags)),
            ] {
                gl.bind_buffer(glow::SHADER_STORAGE_BUFFER, Some(b));
                gl.buffer_sub_data_u8_slice(glow::SHADER_STORAGE_BUFFER, 0, data);
            }
            gl.memory_barrier(glow::BUFFER_UPDATE_BARRIER_BIT);
        }
    }

    /// The gather of the input [`GlGather::set_input`] uploaded, into
    /// [`GlGather::h_buffer`]; nothing is read back.
    pub fn run(&self, gl: &glow::Context) {
        self.dispatch(gl, self.buffers.b0, self.buffers.active);
    }

    /// `H` of the last product, read back (blocking).
    pub fn read_h(&self, gl: &glow::Context) -> Result<[Vec<f32>; 3], GlError> {
        let v = super::read_floats(gl, self.buffers.h, 3 * self.n);
        super::check(gl, "the gather")?;
        let n = self.n;
        Ok(std::array::from_fn(|c| v[c * n..(c + 1) * n].to_vec()))
    }

    /// `H = T̃ · B0` over the `active` tile columns (a tile column with no
    /// active group is not read), three channels of `n`: uploads, runs and
    /// reads back (for tests and reports; a frame uses
    /// [`GlGather::dispatch`] on buffers already on the GPU).
    pub fn gather(
        &self,
        gl: &glow::Context,
        b0: [&[f32]; 3],
        active: &ActiveColumns,
    ) -> Result<[Vec<f32>; 3], GlError> {
        self.set_input(gl, b0, active);
        self.run(gl);
        self.read_h(gl)
    }

    /// Dispatches the three passes (module doc) on the `B0` in storage
    /// buffer `b0` (3 n floats, channel-major) over the tile columns flagged
    /// in `tile_active` (one u32 per tile column), into
    /// [`GlGather::h_buffer`]; nothing is read back. The caller orders
    /// later reads with a barrier.
    pub fn dispatch(&self, gl: &glow::Context, b0: glow::Buffer, tile_active: glow::Buffer) {
        let b = &self.buffers;
        let ssbo = glow::SHADER_STORAGE_BUFFER;
        // SAFETY: binds and dispatches on the current context; the buffers
        // are sized by `new` and the caller.
        unsafe {
            for (k, buffer) in [
                (binding::ROW_START, b.row_start),
                (binding::TILE_COL, b.tile_col),
                (binding::B0, b0),
                (binding::ACTIVE, tile_active),
                (binding::SPARSE_ROW, b.sparse_row),
                (binding::SPARSE_COL, b.sparse_col),
                (binding::SPARSE_VAL, b.sparse_val),
                (binding::H, b.h),
                (binding::DENSE, b.dense),
                (binding::OFFSET, b.offset),
                (binding::COL_SCALE, b.col_scale),
                (binding::X, b.x),
                (binding::LIST, b.list),
                (binding::COUNT, b.count),
                (binding::PARTIAL, b.partial),
            ] {
                gl.bind_buffer_base(ssbo, k, Some(buffer));
            }
            let tps = self.tiles_per_side as u32;
            gl.use_program(Some(self.programs[0]));
            gl.dispatch_compute(tps, 1, 1);
            gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT);
            gl.bind_buffer_base(ssbo, binding::TABLE, Some(b.dense_table));
            gl.use_program(Some(self.programs[1]));
            gl.dispatch_compute(tps, self.slabs as u32, 1);
            gl.memory_barrier(glow::SHADER_STORAGE_BARRIER_BIT);
            gl.bind_buffer_base(ssbo, binding::TABLE, Some(b.sparse_table));
            gl.use_program(Some(self.programs[2]));
            gl.dispatch_compute(self.n.div_ceil(ROWS_PER_GROUP).max(1) as u32, 1, 1);
        }
    }

    /// The storage buffer `H` is written to (3 n floats, channel-major).
    pub fn h_buffer(&self) -> glow::Buffer {
        self.buffers.h
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: the objects were created on this context and are not
        // used after.
        unsafe {
            for p in self.programs {
                gl.delete_program(p);
            }
            for b in self.buffers.all() {
                gl.delete_buffer(b);
            }
        }
    }
}

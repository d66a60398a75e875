//! The sparse part of the CPU gather: the matrix's largest entries, stored
//! exactly beside the dense tiles (RGB9E5, f16 or f32 values). At load they
//! are re-laid by tile and group of 4 columns, so that a row of tiles reads
//! only the entries of its active column groups; per row of tiles the
//! common case (three output channels) lists runs of consecutive active
//! groups and multiplies them in one call, the general case entry by entry.

use super::columns::{active_groups, low_bits, ActiveColumns};
use super::rows::{compact, tile_columns, GatherStats, RowInputs, Rows, NONE};
#[cfg(target_arch = "x86_64")]
use super::x86;
use radiosity_bakefile::codec::rgb9e5;
use radiosity_bakefile::codec::{Encoded, SparseValues};

/// The sparse part as the gather reads it.
pub(super) struct SparseRt {
    /// (tile column, first entry) of each block; a block's entries end
    /// where the next block's start (`entries` closes the list).
    blocks: Vec<(u16, u32)>,
    /// `block_of[tr * tiles_per_side + tc]`: the block of tile (tr, tc),
    /// [`NONE`] where it has no entry.
    block_of: Vec<u32>,
    /// Per block, where each of its groups of 4 columns starts (`tile / 4 +
    /// 1` entry indices, the last closing the block): a tile with some
    /// active column group reads only the entries of its active groups.
    group_start: Vec<u32>,
    /// Per entry: row within the tile (high byte) and column within it.
    pos: Vec<u16>,
    /// RGB9E5 words (precision RGB9E5) or values (f16 and f32: the three
    /// channels and a zero lane, a grey part's value three times).
    packed: Vec<u32>,
    values: Vec<[f32; 4]>,
    /// RGB9E5: `2^(e − 24) / scale_c` per exponent and channel (and a
    /// zero lane).
    exp_factor: [[f32; 4]; 32],
    channels: usize,
    rgb9e5: bool,
}

/// RGB9E5 sparse values' factors: a word's channel `c` is its 9-bit
/// mantissa times `factors[e][c] = 2^(e − 24) / scale_c` (e its 5-bit
/// exponent; lane 3 is 0). Exact: powers of two times a mantissa below
/// 2^9. The CPU gather and the GL gather (`crates/gl/glsl/gather.comp`) both use
/// these f32 values.
pub fn rgb9e5_factors(scale: [f32; 3]) -> [[f32; 4]; 32] {
    let mut exp_factor = [[0.0f32; 4]; 32];
    for (ex, f) in exp_factor.iter_mut().enumerate() {
        for (fc, s) in f.iter_mut().zip(scale) {
            *fc = (2f64.powi(ex as i32 - 24) / s as f64) as f32;
        }
    }
    exp_factor
}

impl SparseRt {
    /// `e`'s sparse part laid out for tiles of `tile` (`tps` per side).
    pub(super) fn new(e: &Encoded, tile: usize, tps: usize) -> SparseRt {
        let sp = &e.sparse;
        let rgb9e5 = sp.precision == SparseValues::Rgb9e5 && !sp.is_empty();
        let exp_factor = rgb9e5_factors(sp.scale);
        // The sparse part re-laid by tile (row of tiles, then tile column,
        // then group of 4 columns, then column and row), so that a skipped
        // tile or column group skips its entries' memory too (the tile
        // edge is a multiple of 4, so groups do not straddle tiles).
        // Column before row: consecutive entries then add to different
        // rows of H, so an entry's add does not wait for the previous
        // one's store (by row first the whole sparse part took 8 % longer
        // on Sponza at 3,946 patches).
        let mut order: Vec<(usize, usize, usize, usize, u32, usize)> = Vec::with_capacity(sp.len());
        for (i, w) in sp.row_ptr.windows(2).enumerate() {
            for k in w[0] as usize..w[1] as usize {
                let j = sp.cols[k];
                order.push((
                    i / tile,
                    j as usize / tile,
                    j as usize / 4,
                    j as usize,
                    i as u32,
                    k,
                ));
            }
        }
        order.sort_unstable();
        let mut block_start = vec![0u32; tps + 1];
        let mut blocks: Vec<(u16, u32)> = Vec::new();
        let mut pos = Vec::with_capacity(order.len());
        let (mut packed, mut values) = (Vec::new(), Vec::new());
        let ch = e.channels;
        let gpt = tile / 4;
        let mut group_start: Vec<u32> = Vec::new();
        for (idx, &(tr, tc, g, j, i, k)) in order.iter().enumerate() {
            if idx == 0 || order[idx - 1].0 != tr || order[idx - 1].1 != tc {
                if !blocks.is_empty() {
                    group_start.resize(blocks.len() * (gpt + 1), idx as u32);
                }
                blocks.push((tc as u16, idx as u32));
            }
            // Groups of this block up to g start here at the latest.
            let base = (blocks.len() - 1) * (gpt + 1);
            let gl = g - tc * gpt;
            while group_start.len() <= base + gl {
                group_start.push(idx as u32);
            }
            block_start[tr + 1] = blocks.len() as u32;
            pos.push((((i as usize % tile) as u16) << 8) | (j % tile) as u16);
            if rgb9e5 {
                let v = &sp.values[3 * k..3 * k + 3];
                packed.push(rgb9e5::pack(std::array::from_fn(|c| v[c] * sp.scale[c])));
            } else {
                let v = &sp.values[ch * k..ch * k + ch];
                values.push([v[0], v[1.min(ch - 1)], v[2.min(ch - 1)], 0.0]);
            }
        }
        for r in 1..=tps {
            block_start[r] = block_start[r].max(block_start[r - 1]);
        }
        group_start.resize(blocks.len() * (gpt + 1), order.len() as u32);
        let mut block_of = vec![NONE; tps * tps];
        for tr in 0..tps {
            for bi in block_start[tr] as usize..block_start[tr + 1] as usize {
                block_of[tr * tps + blocks[bi].0 as usize] = bi as u32;
            }
        }
        blocks.push((u16::MAX, order.len() as u32));
        SparseRt {
            blocks,
            block_of,
            group_start,
            pos,
            packed,
            values,
            exp_factor,
            channels: ch,
            rgb9e5,
        }
    }

    /// Whether there is no entry.
    pub(super) fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }

    /// Row of tiles `tr`'s entries in active columns added into `rows`
    /// (`visit` and `runs`: the caller's scratch), counted in `stats`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn row(
        &self,
        tr: usize,
        tps: usize,
        tile: usize,
        inputs: &RowInputs,
        rows: &mut [[f32; 4]],
        visit: &mut Vec<u32>,
        runs: &mut Vec<[u32; 3]>,
        wide: &mut Vec<[f32; 4]>,
        stats: &mut GatherStats,
    ) {
        let RowInputs {
            b0,
            b0x,
            active,
            out_ch,
            sparse_avx2,
            ..
        } = *inputs;
        #[cfg(not(target_arch = "x86_64"))]
        let _ = sparse_avx2;
        // The sparse part of these rows, tile by tile: its blocks in active
        // tile columns, listed the same way.
        let sp = self;
        let row_of = &sp.block_of[tr * tps..(tr + 1) * tps];
        let listed = compact(visit, &active.tiles, row_of);
        let entry_bytes = if sp.rgb9e5 {
            6
        } else {
            2 + 4 * sp.channels as u64
        };
        let gpt = tile / 4;
        for &bi in &visit[..listed] {
            let bi = bi as usize;
            let tc = sp.blocks[bi].0 as usize;
            let starts = &sp.group_start[bi * (gpt + 1)..(bi + 1) * (gpt + 1)];
            stats.bytes_read += 4 * (gpt as u64 + 1);
            let mut bits = active.mask[tc];
            while bits != 0 {
                let gl = bits.trailing_zeros() as usize;
                // The common case takes a run of consecutive active groups
                // at once (their entries are contiguous, and in the same
                // order): a group holds a few entries, and the cost per
                // call showed (Sponza at 3,946 patches, every column: 2.69
                // → 2.07–2.23 ms for the whole gather).
                let run = if out_ch == 3 {
                    (bits >> gl).trailing_ones() as usize
                } else {
                    1
                };
                bits &= !(low_bits(run) << gl);
                let (a, b) = (starts[gl] as usize, starts[gl + run] as usize);
                stats.bytes_read += (b - a) as u64 * entry_bytes;
                stats.sparse_entries += (b - a) as u64;
                let jb = tc * tile;
                if out_ch == 3 {
                    // The common case: listed, then run in one call below.
                    if a < b {
                        runs.push([a as u32, b as u32, jb as u32]);
                    }
                    continue;
                }
                for e in a..b {
                    let p = sp.pos[e];
                    let (r, j) = ((p >> 8) as usize, jb + (p & 0xff) as usize);
                    let v: [f32; 3] = if sp.rgb9e5 {
                        let p = sp.packed[e];
                        let f = &sp.exp_factor[(p >> 27) as usize];
                        [
                            (p & 0x1ff) as f32 * f[0],
                            ((p >> 9) & 0x1ff) as f32 * f[1],
                            ((p >> 18) & 0x1ff) as f32 * f[2],
                        ]
                    } else {
                        let s = &sp.values[e];
                        [s[0], s[1], s[2]]
                    };
                    for (oc, o) in rows[r].iter_mut().enumerate().take(out_ch) {
                        *o += v[oc] * b0[oc][j];
                    }
                }
            }
        }
        // The common case's runs in one call (a run holds a few entries
        // when few columns are lit, and a call per run showed: Sponza at
        // 3,946 patches, one spot light, the sparse part 1.27× its share
        // of the work). Without per-entry branches, the same operations in
        // the same order as the general loop.
        if runs.is_empty() {
            return;
        }
        // The rows in a 256-row buffer, so that an entry's row (a byte of
        // its position) indexes it without a bounds check, as its column
        // does `b0x` (padded by 256 columns) from its tile's first column:
        // the loops' only checks are per run (the positions were built from
        // rows and columns within the matrix, so no entry reaches past
        // `rows`).
        let h = rows.len();
        let wide: &mut Rows = wide.as_mut_slice().try_into().expect("a 256-row buffer");
        wide[..h].copy_from_slice(rows);
        if !sp.rgb9e5 {
            sparse_values(runs, &sp.pos, &sp.values, b0x, wide);
        } else if cfg!(target_arch = "x86_64") && sparse_avx2 {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `sparse_avx2` is set only where the CPU has AVX2.
            unsafe {
                x86::sparse_rgb9e5_avx2(runs, &sp.pos, &sp.packed, &sp.exp_factor, b0x, wide);
            }
        } else {
            sparse_rgb9e5(runs, &sp.pos, &sp.packed, &sp.exp_factor, b0x, wide);
        }
        rows.copy_from_slice(&wide[..h]);
    }
}

/// The sparse part's common case (RGB9E5 values, three channels): the
/// entries of each run `[first, end, jb]` (in order) into `rows`, per
/// entry its three channels in 4-lane arrays (`b0x` by column, an entry's
/// column `jb` plus its column within the tile). The same operations in
/// the same order as the general loop, so the same bits: per channel the
/// mantissa times its exponent's factor, times `B0`, added to the row.
fn sparse_rgb9e5(
    runs: &[[u32; 3]],
    pos: &[u16],
    packed: &[u32],
    exp_factor: &[[f32; 4]; 32],
    b0x: &[[f32; 4]],
    rows: &mut Rows,
) {
    for &[a, b, jb] in runs {
        let (a, b) = (a as usize, b as usize);
        let b0x = tile_columns(b0x, jb);
        for (&p, &w) in pos[a..b].iter().zip(&packed[a..b]) {
            let f = &exp_factor[(w >> 27) as usize];
            let m = [
                (w & 0x1ff) as f32,
                ((w >> 9) & 0x1ff) as f32,
                ((w >> 18) & 0x1ff) as f32,
                0.0,
            ];
            let b = &b0x[(p & 0xff) as usize];
            let row = &mut rows[(p >> 8) as usize];
            for c in 0..4 {
                row[c] += m[c] * f[c] * b[c];
            }
        }
    }
}

/// The sparse part's runs of f16 or f32 values (stored as f32, three
/// channels and a zero lane): per entry one four-lane multiply and add
/// into its row, the general loop's operations in its order (so the same
/// bits), which the compiler vectorises on every x86-64 (SSE2).
fn sparse_values(
    runs: &[[u32; 3]],
    pos: &[u16],
    values: &[[f32; 4]],
    b0x: &[[f32; 4]],
    rows: &mut Rows,
) {
    for &[a, b, jb] in runs {
        let (a, b) = (a as usize, b as usize);
        let b0x = tile_columns(b0x, jb);
        for (&p, v) in pos[a..b].iter().zip(&values[a..b]) {
            let b = &b0x[(p & 0xff) as usize];
            let row = &mut rows[(p >> 8) as usize];
            for c in 0..4 {
                row[c] += v[c] * b[c];
            }
        }
    }
}

/// Whether [`x86::sparse_rgb9e5_avx2`] can run here.
pub(super) fn sparse_avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `B0` by column into `out`, the three channels side by side and a zero
/// lane: what the sparse part's common case reads. Only the columns of
/// active groups are written, as in
/// [`super::columns::fill_b0_groups`].
pub(super) fn fill_b0_columns(
    b0: [&[f32]; 3],
    active: &ActiveColumns,
    tile: usize,
    out: &mut Vec<[f32; 4]>,
) {
    let n = b0[0].len();
    // 256 columns of zeros past the last: [`tile_columns`].
    out.resize(n + 256, [0.0; 4]);
    for g in active_groups(active, tile) {
        for j in 4 * g..(4 * g + 4).min(n) {
            out[j] = [b0[0][j], b0[1][j], b0[2][j], 0.0];
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use radiosity_core::math::SplitMix64;

    /// The AVX2 sparse loop gives the portable one's bits: random RGB9E5
    /// words (every exponent), positions with repeated rows (the
    /// accumulation order matters), random `B0`.
    #[test]
    fn the_avx2_sparse_loop_changes_no_bit() {
        assert!(
            sparse_avx2_available(),
            "this test compares the AVX2 sparse loop with the portable one: it needs a CPU with AVX2"
        );
        let mut rng = SplitMix64::new(7);
        let mut exp_factor = [[0.0f32; 4]; 32];
        for (e, f) in exp_factor.iter_mut().enumerate() {
            for (c, x) in f.iter_mut().take(3).enumerate() {
                *x = 2f32.powi(e as i32 - 24) / (0.5 + c as f32);
            }
        }
        let entries = 4_000;
        // Rows and columns of every byte value (tiles of up to 256), rows
        // repeated (the accumulation order matters).
        let pos: Vec<u16> = (0..entries).map(|_| rng.next_u64() as u16).collect();
        let packed: Vec<u32> = (0..entries).map(|_| rng.next_u64() as u32).collect();
        // Runs start at tile columns 0..8, so 8 + 256 columns.
        let b0x: Vec<[f32; 4]> = (0..8 + 256)
            .map(|_| {
                let mut v = [0.0f32; 4];
                for x in v.iter_mut().take(3) {
                    *x = (rng.next_u64() % 10_000) as f32 / 977.0;
                }
                v
            })
            .collect();
        let mut a: Rows = [[0.25f32; 4]; 256];
        let mut b = a;
        // Runs of every length, the last reaching the end, some columns on.
        let mut runs = Vec::new();
        let mut a0 = 0u32;
        while (a0 as usize) < entries {
            let end = (a0 + (rng.next_u64() % 40) as u32).min(entries as u32);
            runs.push([a0, end, (rng.next_u64() % 8) as u32]);
            a0 = end + (rng.next_u64() % 3) as u32;
        }
        sparse_rgb9e5(&runs, &pos, &packed, &exp_factor, &b0x, &mut a);
        // SAFETY: checked above that the CPU has AVX2.
        unsafe { x86::sparse_rgb9e5_avx2(&runs, &pos, &packed, &exp_factor, &b0x, &mut b) };
        for (x, y) in a.iter().zip(&b) {
            for c in 0..4 {
                assert_eq!(x[c].to_bits(), y[c].to_bits(), "{x:?} vs {y:?}");
            }
        }
    }
}

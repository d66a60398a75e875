//! The run time's read path: decoding the compressed matrix, tile by tile,
//! and the product `H = T̃ · B0` straight from the compressed form (module
//! doc of [`super`], "Decoding as the run time does"). Decode-only: nothing
//! here depends on the encoder.

use super::{DenseFormat, Encoded};
use half::f16;
// The gathers' sums of products, in f32 (as the run time) or f64 (the
// error measures).
use radiosity_core::products::{add_products, Accumulator, Run};
use rayon::prelude::*;

impl Encoded {
    /// The matrix as the run time sees it (see [`decode`]).
    pub fn decode(&self) -> [Vec<f32>; 3] {
        decode(self)
    }

    /// `H = T̃ · B0` per channel, computed from the compressed form as the
    /// run-time shader does: for each row of tiles, the stored tiles only
    /// (decoded block by block, accumulated in f32 in column order), then
    /// the sparse entries of each row. A grey matrix is decoded once and
    /// multiplied by the three channels of `B0`.
    pub fn gather(&self, b0: [&[f32]; 3]) -> [Vec<f32>; 3] {
        self.gather_in::<f32>(b0)
    }

    /// [`Encoded::gather`] accumulated in f64 (each product of two f32 is
    /// exact in f64), for error measures that must not see f32 summation:
    /// for F32 it equals `bake::encode::mat_vec` bit for bit (same order of terms).
    pub fn gather_f64(&self, b0: [&[f32]; 3]) -> [Vec<f64>; 3] {
        self.gather_in::<f64>(b0)
    }

    /// [`Encoded::gather_f64`] for many `B0` at once, each tile decoded
    /// once for all of them (the bake's error measure over its error
    /// lights: one decode instead of one per light). Every result equals
    /// `gather_f64` of its `B0` bit for bit: the same terms in the same
    /// order.
    pub fn gather_many_f64(&self, b0s: &[[&[f32]; 3]]) -> Vec<[Vec<f64>; 3]> {
        self.gather_many_in::<f64>(b0s, 1)
    }

    /// [`Encoded::gather_many_f64`] of every `stride`-th row of tiles only
    /// (rows `tr · TILE ..` with `tr % stride == 0`, [`TILE`] rows each):
    /// the rows gathered equal `gather_many_f64`'s bit for bit, the others
    /// are 0. The bake's codec choice estimates a candidate's error on
    /// them ([`Encoded::sampled_tile_rows`]).
    ///
    /// [`TILE`]: super::TILE
    pub fn gather_many_f64_sampled(
        &self,
        b0s: &[[&[f32]; 3]],
        stride: usize,
    ) -> Vec<[Vec<f64>; 3]> {
        self.gather_many_in::<f64>(b0s, stride.max(1))
    }

    /// Whether row `i` is among those [`Encoded::gather_many_f64_sampled`]
    /// gathers with `stride`.
    pub fn sampled_tile_rows(&self, i: usize, stride: usize) -> bool {
        (i / self.index.tile).is_multiple_of(stride.max(1))
    }

    /// The gather with accumulators of type `A`.
    fn gather_in<A: Accumulator>(&self, b0: [&[f32]; 3]) -> [Vec<A>; 3] {
        self.gather_many_in::<A>(&[b0], 1)
            .pop()
            .expect("one result per B0")
    }

    /// The gather of every `B0` in `b0s` with accumulators of type `A`:
    /// per row of tiles, the stored tiles decoded once and multiplied by
    /// each `B0` (accumulated in column order), then the sparse entries of
    /// each row; only every `stride`-th row of tiles (the others 0).
    fn gather_many_in<A: Accumulator>(
        &self,
        b0s: &[[&[f32]; 3]],
        stride: usize,
    ) -> Vec<[Vec<A>; 3]> {
        let n = self.n;
        for b0 in b0s {
            for b in b0 {
                assert_eq!(b.len(), n, "B0 must have one value per patch");
            }
        }
        // Column scales: the stored matrix multiplies s ∘ B0.
        let scaled: Vec<[Vec<f32>; 3]> = if self.col_scale.is_empty() {
            Vec::new()
        } else {
            b0s.iter()
                .map(|&b| super::scaled_input(b, &self.col_scale))
                .collect()
        };
        let scaled_refs: Vec<[&[f32]; 3]> = scaled
            .iter()
            .map(|b| [&b[0][..], &b[1][..], &b[2][..]])
            .collect();
        let b0s = if scaled.is_empty() {
            b0s
        } else {
            &scaled_refs[..]
        };
        let k = b0s.len();
        if k == 0 {
            return Vec::new();
        }
        let book = self.codebook();
        let s = self.image_size;
        let tile = self.index.tile;
        let ch = self.channels;
        // B0 converted once and laid out [column][channel][sample], so that
        // each decoded entry meets every sample's value in one contiguous
        // run ([`add_products`] runs along a tile's row with a block of
        // samples' sums in registers). Each accumulator still sums its
        // terms in the same order as a single gather: tiles in column
        // order, columns within a tile in order. B0 stays f32, widened
        // where it is multiplied (exactly).
        let mut b0t = vec![0.0f32; n * 3 * k];
        for (si, b0) in b0s.iter().enumerate() {
            for (oc, b) in b0.iter().enumerate() {
                for (j, &x) in b.iter().enumerate() {
                    b0t[(j * 3 + oc) * k + si] = x;
                }
            }
        }
        // Per row of tiles: acc[row][channel][sample].
        let per_row: Vec<Vec<A>> = (0..self.index.tiles_per_side)
            .into_par_iter()
            .map(|tr| {
                let r0 = tr * tile;
                let h = tile.min(s - r0);
                let mut acc = vec![A::default(); h * 3 * k];
                if !tr.is_multiple_of(stride) {
                    return acc;
                }
                let mut buf = vec![0.0f32; tile * tile * ch];
                self.each_tile_of_row(&book, tr, &mut buf, |t, buf| {
                    for (r, acc_r) in acc.chunks_exact_mut(3 * k).enumerate().take(t.rows) {
                        for (oc, a) in acc_r.chunks_exact_mut(k).enumerate() {
                            // The row's texels of channel `oc` along the
                            // tile, against the columns' samples.
                            let run = Run {
                                x: &buf[r * t.w * ch + oc.min(ch - 1)..],
                                stride_x: ch,
                                b: &b0t[t.c0 * 3 * k + oc * k..],
                                stride_b: 3 * k,
                                cols: t.cols,
                            };
                            add_products(a, run);
                        }
                    }
                });
                acc
            })
            .collect();
        let sp = &self.sparse;
        let sch = self.channels;
        (0..k)
            .into_par_iter()
            .map(|si| {
                let b0 = &b0s[si];
                let mut h: [Vec<A>; 3] = std::array::from_fn(|_| vec![A::default(); n]);
                for (tr, acc) in per_row.iter().enumerate() {
                    for (r, v) in acc.chunks_exact(3 * k).enumerate() {
                        let i = tr * tile + r;
                        if i < n {
                            for (oc, hc) in h.iter_mut().enumerate() {
                                hc[i] = v[oc * k + si];
                            }
                        }
                    }
                }
                if !sp.is_empty() {
                    for (i, window) in sp.row_ptr.windows(2).enumerate() {
                        if !(i / tile).is_multiple_of(stride) {
                            continue;
                        }
                        for e in window[0] as usize..window[1] as usize {
                            let j = sp.cols[e] as usize;
                            for (oc, hc) in h.iter_mut().enumerate() {
                                hc[i] += A::from(sp.values[e * sch + oc.min(sch - 1)])
                                    * A::from(b0[oc][j]);
                            }
                        }
                    }
                }
                h
            })
            .collect()
    }

    /// Per channel, each column's sum of magnitudes `s_j = Σ_i |T̃_ij|` of
    /// the matrix as the run time sees it ([`decode`]: dense tiles, sparse
    /// part, column scales), in f64, without decoding the whole matrix at
    /// once: a row of tiles at a time, each thread summing into its own
    /// columns. `s_j · |x_j|` bounds the L1 norm of the product's part
    /// from column `j`: the run time's culling of negligible columns uses
    /// it. (Entries are ≥ 0 but for a transfer matrix's round-off; the
    /// magnitudes keep the bound whatever their signs.) A grey matrix's
    /// one channel three times.
    pub fn column_sums(&self) -> [Vec<f64>; 3] {
        let n = self.n;
        let book = self.codebook();
        let tile = self.index.tile;
        let ch = self.channels;
        // A few leaves per thread: each fold leaf holds its own sums (8 n
        // bytes a channel), so their number is kept small.
        let leaf = (self.index.tiles_per_side / (4 * rayon::current_num_threads())).max(1);
        let mut sums = (0..self.index.tiles_per_side)
            .into_par_iter()
            .with_min_len(leaf)
            .fold(
                || (vec![0.0f64; ch * n], vec![0.0f32; tile * tile * ch]),
                |(mut sums, mut buf), tr| {
                    self.each_tile_of_row(&book, tr, &mut buf, |t, buf| {
                        for r in 0..t.rows {
                            for c in 0..t.cols {
                                for k in 0..ch {
                                    sums[k * n + t.c0 + c] +=
                                        f64::from(buf[(r * t.w + c) * ch + k]).abs();
                                }
                            }
                        }
                    });
                    (sums, buf)
                },
            )
            .map(|(sums, _)| sums)
            .reduce(
                || vec![0.0f64; ch * n],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    a
                },
            );
        let sp = &self.sparse;
        for (e, &j) in sp.cols.iter().enumerate() {
            for k in 0..ch {
                sums[k * n + j as usize] += f64::from(sp.values[e * ch + k]).abs();
            }
        }
        if !self.col_scale.is_empty() {
            for k in 0..ch {
                for (v, &sc) in sums[k * n..(k + 1) * n].iter_mut().zip(&self.col_scale) {
                    *v *= f64::from(sc).abs();
                }
            }
        }
        std::array::from_fn(|c| sums[c.min(ch - 1) * n..(c.min(ch - 1) + 1) * n].to_vec())
    }

    /// Decodes the stored tiles of row of tiles `tr`, in order, each into
    /// `buf` (texel-major, `channels` values a texel), and calls `f` with
    /// its place ([`TilePlace`]).
    fn each_tile_of_row(
        &self,
        book: &Codebook,
        tr: usize,
        buf: &mut [f32],
        mut f: impl FnMut(TilePlace, &[f32]),
    ) {
        let (tile, s, n) = (self.index.tile, self.image_size, self.n);
        let r0 = tr * tile;
        let h = tile.min(s - r0);
        let rows = h.min(n.saturating_sub(r0));
        for slot in self.index.row_start[tr] as usize..self.index.row_start[tr + 1] as usize {
            let c0 = self.index.cols[slot] as usize * tile;
            let w = tile.min(s - c0);
            self.decode_tile(book, slot, h, w, buf);
            let cols = w.min(n.saturating_sub(c0));
            f(TilePlace { c0, w, rows, cols }, buf);
        }
    }

    /// The tables and scales the decoder needs.
    pub fn codebook(&self) -> Codebook {
        let mut lut = [[0.0f32; 256]; 3];
        let mut inv_scale = [1.0f32; 3];
        for c in 0..3 {
            match self.format {
                DenseFormat::Bc1 | DenseFormat::Bc4 => {
                    lut[c] = log_lut(self.scale[c], self.log_range);
                }
                DenseFormat::Bc6h | DenseFormat::F16 => inv_scale[c] = 1.0 / self.scale[c],
                DenseFormat::F32 => {}
            }
        }
        Codebook {
            format: self.format,
            channels: self.channels,
            lut,
            max: self.scale,
            log_range: self.log_range,
            inv_scale,
        }
    }

    /// Decodes stored tile `slot` (h × w texels) into `out` (texel-major,
    /// `channels` values per texel).
    fn decode_tile(&self, book: &Codebook, slot: usize, h: usize, w: usize, out: &mut [f32]) {
        let start = self.index.offsets[slot] as usize;
        let len = self.format.tile_bytes(h, w, self.channels);
        decode_tile_bytes(book, &self.dense[start..start + len], h, w, out);
    }
}

/// Where a decoded tile lies ([`Encoded::each_tile_of_row`]): its first
/// column, its width in texels, and the rows and columns of it inside the
/// matrix (the padding past `n` left out).
#[derive(Clone, Copy)]
struct TilePlace {
    c0: usize,
    w: usize,
    rows: usize,
    cols: usize,
}

/// What decoding a tile needs (the encoder decodes what it wrote with it
/// too, for the mass correction).
pub struct Codebook {
    pub format: DenseFormat,
    pub channels: usize,
    /// BC1: value of each byte per channel.
    pub lut: [[f32; 256]; 3],
    /// BC4: the maxima `M_c`.
    pub max: [f32; 3],
    pub log_range: f32,
    /// F16 and BC6H: 1 / scale (a power of two, exact).
    pub inv_scale: [f32; 3],
}

/// The value of each log byte: 0 for byte 0, `M · e^{L (q/255 − 1)}` else.
pub fn log_lut(max: f32, log_range: f32) -> [f32; 256] {
    let mut lut = [0.0f32; 256];
    for (q, v) in lut.iter_mut().enumerate().skip(1) {
        *v = (max as f64 * (log_range as f64 * (q as f64 / 255.0 - 1.0)).exp()) as f32;
    }
    lut
}

/// The value of a BC4 texel decoded at float precision `x ∈ [0, 1]`.
fn log_value(x: f32, max: f32, log_range: f32) -> f32 {
    if x <= 0.0 {
        0.0
    } else {
        max * (log_range * (x - 1.0)).exp()
    }
}

/// Decodes one tile's bytes into values (texel-major, `channels` per texel).
pub fn decode_tile_bytes(book: &Codebook, bytes: &[u8], h: usize, w: usize, out: &mut [f32]) {
    let ch = book.channels;
    let (bh, bw) = (h / 4, w / 4);
    match book.format {
        DenseFormat::Bc1 => {
            let mut rgba = [0u8; 64];
            for by in 0..bh {
                for bx in 0..bw {
                    let k = by * bw + bx;
                    bcdec_rs::bc1(&bytes[k * 8..k * 8 + 8], &mut rgba, 16);
                    for y in 0..4 {
                        for x in 0..4 {
                            let t = ((by * 4 + y) * w + bx * 4 + x) * 3;
                            let p = (y * 4 + x) * 4;
                            for c in 0..3 {
                                out[t + c] = book.lut[c][rgba[p + c] as usize];
                            }
                        }
                    }
                }
            }
        }
        DenseFormat::Bc4 => {
            let plane = bh * bw * 8;
            let mut vals = [0.0f32; 16];
            for c in 0..ch {
                for by in 0..bh {
                    for bx in 0..bw {
                        let k = c * plane + (by * bw + bx) * 8;
                        bcdec_rs::bc4_float(&bytes[k..k + 8], &mut vals, 4, false);
                        for y in 0..4 {
                            for x in 0..4 {
                                let t = ((by * 4 + y) * w + bx * 4 + x) * ch + c;
                                out[t] = log_value(vals[y * 4 + x], book.max[c], book.log_range);
                            }
                        }
                    }
                }
            }
        }
        DenseFormat::Bc6h => {
            let mut halves = [0u16; 48];
            for by in 0..bh {
                for bx in 0..bw {
                    let k = (by * bw + bx) * 16;
                    bcdec_rs::bc6h_half(&bytes[k..k + 16], &mut halves, 12, false);
                    for y in 0..4 {
                        for x in 0..4 {
                            let t = ((by * 4 + y) * w + bx * 4 + x) * 3;
                            for c in 0..3 {
                                out[t + c] = f16::from_bits(halves[(y * 4 + x) * 3 + c]).to_f32()
                                    * book.inv_scale[c];
                            }
                        }
                    }
                }
            }
        }
        DenseFormat::F16 => {
            for (k, v) in out[..h * w * ch].iter_mut().enumerate() {
                let bits = u16::from_le_bytes([bytes[2 * k], bytes[2 * k + 1]]);
                *v = f16::from_bits(bits).to_f32() * book.inv_scale[k % ch];
            }
        }
        DenseFormat::F32 => {
            for (k, v) in out[..h * w * ch].iter_mut().enumerate() {
                *v = f32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap());
            }
        }
    }
}

/// The matrix as the run time sees it: dense tiles decoded (skipped tiles
/// are zero) plus the sparse part, times the column scales where there are
/// any, three channels (a grey matrix's one channel three times).
pub fn decode(e: &Encoded) -> [Vec<f32>; 3] {
    let n = e.n;
    let s = e.image_size;
    let tile = e.index.tile;
    let ch = e.channels;
    let book = e.codebook();
    let mut out: Vec<Vec<f32>> = (0..ch).map(|_| vec![0.0f32; n * n]).collect();
    // Rows of tiles in parallel: each owns a band of rows of the output.
    let bands: Vec<Vec<Vec<f32>>> = (0..e.index.tiles_per_side)
        .into_par_iter()
        .map(|tr| {
            let r0 = tr * tile;
            let rows = tile.min(n.saturating_sub(r0));
            let h = tile.min(s - r0);
            let mut band: Vec<Vec<f32>> = (0..ch).map(|_| vec![0.0f32; rows * n]).collect();
            let mut buf = vec![0.0f32; tile * tile * ch];
            for slot in e.index.row_start[tr] as usize..e.index.row_start[tr + 1] as usize {
                let c0 = e.index.cols[slot] as usize * tile;
                let w = tile.min(s - c0);
                e.decode_tile(&book, slot, h, w, &mut buf);
                for r in 0..rows {
                    for c in 0..w.min(n.saturating_sub(c0)) {
                        for (k, b) in band.iter_mut().enumerate() {
                            b[r * n + c0 + c] = buf[(r * w + c) * ch + k];
                        }
                    }
                }
            }
            band
        })
        .collect();
    for (tr, band) in bands.into_iter().enumerate() {
        let r0 = tr * tile;
        for (k, b) in band.into_iter().enumerate() {
            out[k][r0 * n..r0 * n + b.len()].copy_from_slice(&b);
        }
    }
    let sp = &e.sparse;
    for (i, window) in sp.row_ptr.windows(2).enumerate() {
        for p in window[0] as usize..window[1] as usize {
            let j = sp.cols[p] as usize;
            for (k, o) in out.iter_mut().enumerate() {
                // The dense texel at a sparse position decodes to exactly 0.
                o[i * n + j] += sp.values[p * ch + k];
            }
        }
    }
    // Column scales: T̃ = T' diag(s) (one f32 product per entry).
    if !e.col_scale.is_empty() {
        for o in &mut out {
            o.par_chunks_mut(n.max(1)).for_each(|row| {
                for (v, s) in row.iter_mut().zip(&e.col_scale) {
                    *v *= s;
                }
            });
        }
    }
    if ch == 1 {
        let m = out.pop().unwrap();
        [m.clone(), m.clone(), m]
    } else {
        let mut it = out.into_iter();
        [it.next().unwrap(), it.next().unwrap(), it.next().unwrap()]
    }
}

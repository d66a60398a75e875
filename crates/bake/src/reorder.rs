//! Reordering of patches before compression (docs/design.md section 1, bake step
//! 5): a symmetric permutation `P T Pᵀ` of the transfer matrix's rows and
//! columns that puts similar rows (and so similar columns) next to each
//! other, so that the 4×4 blocks of the block-compressed texture
//! ([`radiosity_bakefile::codec`]) hold similar values. The product is unchanged up to
//! relabelling: `(P T Pᵀ)(P B0) = P (T B0)`.
//!
//! Methods ([`ReorderMethod`]):
//! - **Greedy** nearest neighbour, the thesis's method: start from row 0 and
//!   repeatedly append the nearest unvisited row, by the Euclidean distance
//!   between rows' *feature vectors* ([`Features`]): the row's three colour
//!   channels concatenated (a grey matrix uses one channel: the same order,
//!   a third of the work), each entry in log scale,
//!   `(ln(max(t / M_c, e^{−12})) + 12) / 12` with `M_c` the channel's
//!   maximum. Log scale because the codec quantises `ln t`: rows alike in
//!   log scale give blocks with a narrow log range. Raw values let the few
//!   largest entries decide every distance; on the synthetic room (n = 1632,
//!   BC1, top 2 %) log features lower H's error by 10–25 % against raw ones.
//!   The distances are the O(n³) part: all pairs are computed by the OpenCL
//!   kernel `crates/bake/kernels/reorder.cl` (tiled, upper triangle only, in batches of
//!   rows), or on the CPU in f64 ([`cpu_distances`], the reference, via the
//!   Gram matrix with faer). The chain itself is O(n²) on the host; ties go
//!   to the lower index, so the order is deterministic.
//!   *Passes.* Euclidean row distances do not change when columns are
//!   permuted, so the same chain run again on the reordered matrix from its
//!   row 0 would reproduce itself. Passes after the first are therefore
//!   2-opt sweeps over the chain ([`two_opt_sweep`]: reverse a segment when
//!   that shortens the chain), O(n²) each with the distance matrix already
//!   there; they can only shorten the chain. The default is two passes (the
//!   thesis's count); on the room the sweep shortens the chain by a few per
//!   cent and changes the codec's error by about 1 %.
//!   Memory: the n × 3n feature matrix (host and device) and the n × n
//!   distance matrix (host); beyond [`MAX_GREEDY_PATCHES`] the method is
//!   refused with a message pointing to the curve order.
//! - **SpaceFillingCurve**: patches sorted by (facing direction, 3-D Hilbert
//!   index of the centre quantised to 16 bits per axis over the bounding
//!   cube of all centres). Patches that face the same way and lie close
//!   together see nearly the same scene, so their rows are similar; patches
//!   of one voxel facing different ways see different halves of the scene
//!   and are kept apart. O(n log n), independent of `T`.
//! - **None**: the voxelizer's order (sorted by voxel key), the baseline.
//!
//! **Default** ([`ReorderMethod::default_for`]): greedy with two passes up
//! to [`GREEDY_DEFAULT_MAX_PATCHES`], the curve order beyond. On the
//! synthetic room (n = 1632, BC1 + log + top 2 %) the H error is 0.73 %
//! after greedy, 1.18 % after the curve and 2.26 % in voxel order; greedy
//! took ~1 s on 2 CPU cores there and grows as n³.
//!
//! [`ReorderStats`] reports the time and the mean distance between
//! consecutive feature rows before and after, the quantity the greedy chain
//! minimises.

use crate::compute::Backend;
use radiosity_core::permutation::Permutation;

use crate::compute::{Access, Gpu};
use crate::error::BakeError;
use radiosity_core::patch::Patch;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// The kernel source, embedded.
pub const KERNEL_SOURCE: &str = include_str!("../kernels/reorder.cl");

/// The largest patch count the greedy method accepts: its n × 3n f32
/// feature matrix then takes 768 MiB (host and device) and the n × n
/// distance matrix 256 MiB of host memory; the O(n³) distance computation
/// is ~1.2e12 flops (seconds on a GPU, minutes on a CPU).
pub const MAX_GREEDY_PATCHES: usize = 8192;

/// The largest patch count for which [`ReorderMethod::default_for`] picks
/// the greedy method (its O(n³) distances on the CPU path: ~1 s at
/// n = 1632 and ~5 s at 2496 on two cores, so ~20 s at 4096; PoCL's
/// OpenCL path is ~25× slower than that, a GPU far faster).
pub const GREEDY_DEFAULT_MAX_PATCHES: usize = 4096;

/// Bits per axis of the quantised centres in the Hilbert order.
pub const HILBERT_BITS: u32 = 16;

/// How patches are reordered before compression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ReorderMethod {
    /// Keep the voxelizer's order.
    None,
    /// Greedy nearest-neighbour chain over row distances (the thesis), then
    /// `passes − 1` 2-opt sweeps (module doc); `passes ≥ 1`.
    Greedy { passes: u32 },
    /// Facing direction, then the Hilbert order of patch centres.
    SpaceFillingCurve,
}

impl ReorderMethod {
    /// The default for `n` patches (module doc): greedy with two passes up
    /// to [`GREEDY_DEFAULT_MAX_PATCHES`], else the curve order.
    pub fn default_for(n: usize) -> ReorderMethod {
        if n <= GREEDY_DEFAULT_MAX_PATCHES {
            ReorderMethod::Greedy { passes: 2 }
        } else {
            ReorderMethod::SpaceFillingCurve
        }
    }

    /// A short name for tables and logs.
    pub fn name(&self) -> String {
        match self {
            ReorderMethod::None => "none".into(),
            ReorderMethod::Greedy { passes } => format!("greedy:{passes}"),
            ReorderMethod::SpaceFillingCurve => "hilbert".into(),
        }
    }

    /// Parses `none`, `greedy`, `greedy:N` (N passes, default 2) or
    /// `hilbert` (also `sfc`).
    pub fn parse(s: &str) -> Result<ReorderMethod, BakeError> {
        let s = s.trim().to_ascii_lowercase();
        match s.as_str() {
            "none" => Ok(ReorderMethod::None),
            "hilbert" | "sfc" | "space-filling-curve" => Ok(ReorderMethod::SpaceFillingCurve),
            "greedy" => Ok(ReorderMethod::Greedy { passes: 2 }),
            _ => match s.strip_prefix("greedy:").map(str::parse::<u32>) {
                Some(Ok(passes)) if passes >= 1 => Ok(ReorderMethod::Greedy { passes }),
                _ => Err(BakeError::InvalidOption {
                    option: "reordering",
                    value: format!("{s:?}"),
                    expected: "none, greedy, greedy:PASSES (≥ 1) or hilbert".into(),
                }),
            },
        }
    }
}

impl std::fmt::Display for ReorderMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// Time and quality of one reordering.
#[derive(Clone, Debug, Serialize)]
pub struct ReorderStats {
    pub method: String,
    pub n: usize,
    /// Wall-clock seconds of the whole reordering.
    pub seconds: f64,
    /// Device seconds of the distance kernel (greedy on OpenCL), else 0.
    pub kernel_seconds: f64,
    /// Mean Euclidean distance between consecutive rows (three channels
    /// concatenated), before and after.
    pub adjacent_distance_before: f64,
    pub adjacent_distance_after: f64,
    /// Greedy only: the chain length (sum of consecutive distances) of
    /// every pass, the kept one being the smallest.
    pub chain_lengths: Vec<f64>,
}

fn check_input(t: [&[f32]; 3], n: usize) -> Result<(), BakeError> {
    for (c, ch) in t.iter().enumerate() {
        if ch.len() != n * n {
            return Err(BakeError::Mismatch {
                stage: "reorder",
                detail: format!(
                    "transfer channel {c} has {} entries, expected n² = {}",
                    ch.len(),
                    n * n
                ),
            });
        }
    }
    Ok(())
}

/// Reorders `n` patches (module doc). `t` holds the three channels of the
/// n × n row-major transfer matrix; `patches` (the same `n` patches) is
/// needed by the curve order only. Returns `order[new] = old`.
pub fn reorder(
    method: ReorderMethod,
    t: [&[f32]; 3],
    n: usize,
    patches: &[Patch],
    backend: Backend,
) -> Result<Permutation, BakeError> {
    reorder_with_stats(method, t, n, patches, backend).map(|(p, _)| p)
}

/// [`reorder`] with its time and quality.
pub fn reorder_with_stats(
    method: ReorderMethod,
    t: [&[f32]; 3],
    n: usize,
    patches: &[Patch],
    backend: Backend,
) -> Result<(Permutation, ReorderStats), BakeError> {
    check_input(t, n)?;
    let start = Instant::now();
    let channels = radiosity_bakefile::codec::distinct_channels(t);
    let features = Features::new(&channels, n);
    let mut kernel_seconds = 0.0;
    let mut chain_lengths = Vec::new();
    let perm = match method {
        ReorderMethod::None => Permutation::identity(n),
        ReorderMethod::SpaceFillingCurve => {
            if patches.len() != n {
                return Err(BakeError::Mismatch {
                    stage: "reorder",
                    detail: format!(
                        "the curve order needs the {n} patches of the matrix, got {}",
                        patches.len()
                    ),
                });
            }
            hilbert_order(patches)
        }
        ReorderMethod::Greedy { passes } => {
            if passes == 0 {
                return Err(BakeError::InvalidOption {
                    option: "greedy reordering passes",
                    value: "0".into(),
                    expected: "at least 1".into(),
                });
            }
            if n > MAX_GREEDY_PATCHES {
                return Err(BakeError::TooLarge {
                    stage: "reorder",
                    detail: format!(
                        "greedy reordering of {n} patches needs an n × n distance matrix \
                     ({:.1} GiB) and O(n³) work; the limit is {MAX_GREEDY_PATCHES} patches: \
                     use the Hilbert curve order instead",
                        (n * n * 4) as f64 / (1u64 << 30) as f64
                    ),
                });
            }
            let x = features.matrix();
            let d = features.dim();
            let dist = match backend {
                Backend::Cpu => cpu_distances(&x, n, d),
                Backend::OpenCl(gpu) => {
                    let (dist, secs) = cl_distances(gpu, &x, n, d)?;
                    kernel_seconds = secs;
                    dist
                }
            };
            let (order, lengths) = greedy(&dist, n, passes);
            chain_lengths = lengths;
            Permutation::from_order(order)?
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    let stats = ReorderStats {
        method: method.name(),
        n,
        seconds,
        kernel_seconds,
        adjacent_distance_before: adjacent_distance(&features, &Permutation::identity(n)),
        adjacent_distance_after: adjacent_distance(&features, &perm),
        chain_lengths,
    };
    Ok((perm, stats))
}

/// The range of the log features, `L_f` (module doc): entries below
/// `e^{−L_f}` of their channel's maximum count as that floor.
pub const FEATURE_LOG_RANGE: f32 = 12.0;

/// The greedy method's feature vectors (module doc): row i of every
/// distinct channel, concatenated, each entry mapped to
/// `(ln(max(t / M_c, e^{−L_f})) + L_f) / L_f ∈ [0, 1]`, where `M_c` is the
/// channel's maximum.
pub struct Features<'a> {
    channels: Vec<&'a [f32]>,
    inv_max: Vec<f32>,
    n: usize,
}

impl<'a> Features<'a> {
    pub fn new(channels: &[&'a [f32]], n: usize) -> Features<'a> {
        let inv_max = radiosity_bakefile::codec::inverse_maxima(channels);
        Features {
            channels: channels.to_vec(),
            inv_max,
            n,
        }
    }

    /// Length of a feature vector: n per distinct channel.
    pub fn dim(&self) -> usize {
        self.n * self.channels.len()
    }

    /// Writes row i's features into `out` (length [`Self::dim`]).
    pub fn row(&self, i: usize, out: &mut [f32]) {
        let (n, l) = (self.n, FEATURE_LOG_RANGE);
        let floor = (-l).exp();
        for (c, ch) in self.channels.iter().enumerate() {
            let src = &ch[i * n..(i + 1) * n];
            for (o, &v) in out[c * n..(c + 1) * n].iter_mut().zip(src) {
                *o = ((v * self.inv_max[c]).max(floor).ln() + l) / l;
            }
        }
    }

    /// All rows, n × dim row-major.
    pub fn matrix(&self) -> Vec<f32> {
        let d = self.dim();
        let mut x = vec![0.0f32; self.n * d];
        x.par_chunks_mut(d.max(1))
            .enumerate()
            .for_each(|(i, row)| self.row(i, row));
        x
    }
}

/// Mean Euclidean distance between consecutive feature rows in the order
/// `perm` (rows computed on the fly: no n × d matrix).
pub fn adjacent_distance(features: &Features, perm: &Permutation) -> f64 {
    let n = perm.len();
    if n < 2 {
        return 0.0;
    }
    let d = features.dim();
    let total: f64 = (0..n - 1)
        .into_par_iter()
        .map_init(
            || (vec![0.0f32; d], vec![0.0f32; d]),
            |(a, b), k| {
                features.row(perm.order[k] as usize, a);
                features.row(perm.order[k + 1] as usize, b);
                a.iter()
                    .zip(b.iter())
                    .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
                    .sum::<f64>()
                    .sqrt()
            },
        )
        .sum();
    total / (n - 1) as f64
}

/// Squared distances between all rows of `x` (n × d), the CPU reference:
/// f64 Gram matrix `G = X Xᵀ` with faer, `D_ik = G_ii + G_kk − 2 G_ik`
/// (clamped at 0: rounding can make it slightly negative). In f64 the
/// cancellation that rules the Gram form out in f32 costs ~1e-16 · |x|²,
/// far below the f32 resolution of the kernel's result.
pub fn cpu_distances(x: &[f32], n: usize, d: usize) -> Vec<f32> {
    assert_eq!(x.len(), n * d);
    if n == 0 {
        return Vec::new();
    }
    let xm = faer::Mat::<f64>::from_fn(n, d, |i, j| x[i * d + j] as f64);
    let mut g = faer::Mat::<f64>::zeros(n, n);
    faer::linalg::matmul::matmul(
        g.as_mut(),
        faer::Accum::Replace,
        xm.as_ref(),
        xm.transpose(),
        1.0,
        faer::Par::rayon(0),
    );
    let mut out = vec![0.0f32; n * n];
    out.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
        for (k, o) in row.iter_mut().enumerate() {
            // Symmetric by construction: the same expression for (i, k) and
            // (k, i), with G_ik read from the upper triangle.
            let (a, b) = if i <= k { (i, k) } else { (k, i) };
            *o = if i == k {
                0.0
            } else {
                (g[(a, a)] + g[(b, b)] - 2.0 * g[(a, b)]).max(0.0) as f32
            };
        }
    });
    out
}

/// Bytes of device memory one batch of distance rows may take.
const DISTANCE_BATCH_BYTES: u64 = 256 << 20;

/// Squared distances between all rows of `x` (n × d) with the OpenCL kernel,
/// in batches of rows that fit the device's allocation limit. Returns the
/// symmetric n × n matrix (upper triangle computed, mirrored on the host)
/// and the summed kernel time.
pub fn cl_distances(
    gpu: &Gpu,
    x: &[f32],
    n: usize,
    d: usize,
) -> Result<(Vec<f32>, f64), BakeError> {
    cl_distances_batched(gpu, x, n, d, DISTANCE_BATCH_BYTES)
}

/// [`cl_distances`] with batches of at most `batch_bytes` of output (at
/// least one work-group's rows): tests exercise the batching with it.
pub fn cl_distances_batched(
    gpu: &Gpu,
    x: &[f32],
    n: usize,
    d: usize,
    batch_bytes: u64,
) -> Result<(Vec<f32>, f64), BakeError> {
    assert_eq!(x.len(), n * d);
    if n == 0 {
        return Ok((Vec::new(), 0.0));
    }
    if n > u32::MAX as usize || d > u32::MAX as usize {
        return Err(BakeError::TooLarge {
            stage: "reorder",
            detail: format!("{n} × {d} features exceed the 2^32 limit"),
        });
    }
    // 16 × 16 work-groups where the device allows 256 work-items, else 8 × 8.
    let mut tile = if gpu.info().max_work_group_size >= 256 {
        16
    } else {
        8
    };
    let (_program, kernel) = loop {
        let program = gpu.build("reorder.cl", KERNEL_SOURCE, &format!("-DTILE={tile}"))?;
        let kernel = gpu.kernel(&program, "pair_distances")?;
        if gpu.local_size(&kernel, tile * tile) >= tile * tile || tile == 1 {
            break (program, kernel);
        }
        tile /= 2;
    };
    gpu.check_total("reorder", (x.len() * 4) as u64)?;
    let x_buf = gpu.upload("reorder features", x, Access::ReadOnly)?;
    let row_bytes = (n * 4) as u64;
    let limit = gpu.info().max_mem_alloc_bytes.min(batch_bytes);
    let batch_rows =
        (((limit / row_bytes) as usize / tile) * tile).clamp(tile, n.div_ceil(tile) * tile);
    let out_buf = gpu.buffer::<f32>("distance rows", batch_rows * n, Access::WriteOnly)?;
    let mut dist = vec![0.0f32; n * n];
    let mut seconds = 0.0;
    let n_u32 = n as u32;
    let d_u32 = d as u32;
    let mut row0 = 0usize;
    while row0 < n {
        let rows = batch_rows.min(n - row0);
        let (row0_u32, rows_u32) = (row0 as u32, rows as u32);
        let global = [n.div_ceil(tile) * tile, rows.div_ceil(tile) * tile];
        seconds += gpu.timed("pair_distances", || unsafe {
            opencl3::kernel::ExecuteKernel::new(&kernel)
                .set_arg(&x_buf)
                .set_arg(&n_u32)
                .set_arg(&d_u32)
                .set_arg(&row0_u32)
                .set_arg(&rows_u32)
                .set_arg(&out_buf)
                .set_global_work_sizes(&global)
                .set_local_work_sizes(&[tile, tile])
                .enqueue_nd_range(gpu.queue())
        })?;
        let block = gpu.download("distance rows", &out_buf, rows * n)?;
        dist[row0 * n..(row0 + rows) * n].copy_from_slice(&block);
        row0 += rows;
    }
    // Mirror the upper triangle (the kernel skips blocks below the
    // diagonal; entries below it in computed blocks are replaced too, so the
    // result is exactly symmetric) and zero the diagonal.
    mirror_upper(&mut dist, n);
    Ok((dist, seconds))
}

/// Copies the strict upper triangle onto the lower one and zeroes the
/// diagonal.
fn mirror_upper(dist: &mut [f32], n: usize) {
    for i in 0..n {
        dist[i * n + i] = 0.0;
        for k in 0..i {
            dist[i * n + k] = dist[k * n + i];
        }
    }
}

/// The greedy chain over the symmetric distance matrix `dist` starting at
/// `start`: repeatedly the nearest unvisited row, ties to the lower index.
/// Returns the chain and its length (sum of the distances between
/// consecutive rows, square roots of the squared distances).
pub fn greedy_chain(dist: &[f32], n: usize, start: usize) -> (Vec<u32>, f64) {
    let mut chain = Vec::with_capacity(n);
    if n == 0 {
        return (chain, 0.0);
    }
    let mut unvisited: Vec<u32> = (0..n as u32).filter(|&k| k as usize != start).collect();
    chain.push(start as u32);
    let mut current = start;
    let mut length = 0.0f64;
    while !unvisited.is_empty() {
        let row = &dist[current * n..(current + 1) * n];
        let mut best = 0usize;
        for (pos, &k) in unvisited.iter().enumerate().skip(1) {
            let (dk, db) = (row[k as usize], row[unvisited[best] as usize]);
            if dk < db || (dk == db && k < unvisited[best]) {
                best = pos;
            }
        }
        let next = unvisited.swap_remove(best) as usize;
        length += (row[next] as f64).sqrt();
        chain.push(next as u32);
        current = next;
    }
    (chain, length)
}

/// The greedy method's passes (module doc): the greedy chain from row 0,
/// then up to `passes − 1` 2-opt sweeps (stopping early once a sweep finds
/// nothing). Returns the chain and its length after every pass.
pub fn greedy(dist: &[f32], n: usize, passes: u32) -> (Vec<u32>, Vec<f64>) {
    let (mut chain, len) = greedy_chain(dist, n, 0);
    let mut lengths = vec![len];
    for _ in 1..passes {
        let improved = two_opt_sweep(dist, n, &mut chain);
        lengths.push(chain_length(dist, n, &chain));
        if !improved {
            break;
        }
    }
    (chain, lengths)
}

/// Sum of the distances between consecutive rows of `chain`.
pub fn chain_length(dist: &[f32], n: usize, chain: &[u32]) -> f64 {
    chain
        .windows(2)
        .map(|w| (dist[w[0] as usize * n + w[1] as usize] as f64).sqrt())
        .sum()
}

/// One first-improvement 2-opt sweep over an open chain (Croes, "A method
/// for solving traveling-salesman problems", Oper. Res. 6, 1958): for every
/// segment `chain[i+1..=j]` (a prefix when i = −1, a suffix when j = n−1),
/// reverse it when that shortens the chain, i.e. when
/// `d(c_i, c_j) + d(c_{i+1}, c_{j+1}) < d(c_i, c_{i+1}) + d(c_j, c_{j+1})`
/// (terms with an index outside the chain left out). Returns whether
/// anything changed. Deterministic: a fixed scan order, and a move must
/// gain more than 1e-12 of the edges it replaces, so rounding cannot cycle.
pub fn two_opt_sweep(dist: &[f32], n: usize, chain: &mut [u32]) -> bool {
    let d = |a: u32, b: u32| (dist[a as usize * n + b as usize] as f64).sqrt();
    let mut changed = false;
    if n < 3 {
        return false;
    }
    // `i` is the position before the segment, offset by one (0 = none).
    for i1 in 0..n - 1 {
        for j in i1 + 1..n {
            let seg_start = i1; // first position of the segment
            if seg_start == 0 && j == n - 1 {
                continue; // reversing the whole chain changes nothing
            }
            let mut old = 0.0;
            let mut new = 0.0;
            if seg_start > 0 {
                let a = chain[seg_start - 1];
                old += d(a, chain[seg_start]);
                new += d(a, chain[j]);
            }
            if j + 1 < n {
                let b = chain[j + 1];
                old += d(chain[j], b);
                new += d(chain[seg_start], b);
            }
            if old - new > 1e-12 * old {
                chain[seg_start..=j].reverse();
                changed = true;
            }
        }
    }
    changed
}

/// The 3-D Hilbert index of a point with `bits` bits per coordinate
/// (Skilling, "Programming the Hilbert curve", AIP Conf. Proc. 707, 2004:
/// AxesToTranspose, then the transposed bits interleaved, most significant
/// first).
pub fn hilbert_index(mut x: [u32; 3], bits: u32) -> u64 {
    assert!((1..=21).contains(&bits));
    let m = 1u32 << (bits - 1);
    // Inverse undo.
    let mut q = m;
    while q > 1 {
        let p = q - 1;
        for i in 0..3 {
            if x[i] & q != 0 {
                x[0] ^= p;
            } else {
                let t = (x[0] ^ x[i]) & p;
                x[0] ^= t;
                x[i] ^= t;
            }
        }
        q >>= 1;
    }
    // Gray encode.
    for i in 1..3 {
        x[i] ^= x[i - 1];
    }
    let mut t = 0u32;
    let mut q = m;
    while q > 1 {
        if x[2] & q != 0 {
            t ^= q - 1;
        }
        q >>= 1;
    }
    for v in &mut x {
        *v ^= t;
    }
    let mut h = 0u64;
    for bit in (0..bits).rev() {
        for v in &x {
            h = (h << 1) | ((v >> bit) & 1) as u64;
        }
    }
    h
}

/// Patches sorted by (direction, Hilbert index of the quantised centre,
/// original index): the curve order of the module doc.
pub fn hilbert_order(patches: &[Patch]) -> Permutation {
    let n = patches.len();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in patches {
        for a in 0..3 {
            lo[a] = lo[a].min(p.centre[a]);
            hi[a] = hi[a].max(p.centre[a]);
        }
    }
    // One scale for all axes (the bounding cube), so that the curve's cells
    // are cubes and distances keep their meaning along every axis.
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    let cells = ((1u64 << HILBERT_BITS) - 1) as f64;
    let scale = if extent > 0.0 { cells / extent } else { 0.0 };
    let mut keys: Vec<(u8, u64, u32)> = patches
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q: [u32; 3] = std::array::from_fn(|a| {
                ((p.centre[a] - lo[a]) * scale).round().clamp(0.0, cells) as u32
            });
            (p.direction as u8, hilbert_index(q, HILBERT_BITS), i as u32)
        })
        .collect();
    keys.sort_unstable();
    debug_assert_eq!(keys.len(), n);
    Permutation::from_order(keys.into_iter().map(|k| k.2).collect())
        .expect("sorted indices form a permutation")
}

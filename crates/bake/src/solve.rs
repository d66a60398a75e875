//! `T_∞` by a direct solve on the OpenCL device (the transfer stage's
//! default for infinite bounces; doubling stays as an option and for
//! `T_k`, [`crate::transfer`]).
//!
//! **The system.** `T_∞ = F M⁻¹` with `M = I − diag(ρ) F`, so `T_∞` solves
//! `X M = F`. `M` is a non-singular M-matrix: its off-diagonal entries are
//! `−ρ_i F_ij ≤ 0` and every row is strictly diagonally dominant
//! (`Σ_j ρ_i F_ij ≤ ρ_i < 1` for physical form factors). Hence
//! - LU without pivoting exists and is stable (diagonal dominance bounds
//!   the growth factor by 2; Golub & Van Loan, "Matrix Computations", 4th
//!   ed., 3.4.3), and a zero-albedo patch is just an identity row;
//! - every Schur complement is again an M-matrix, `L⁻¹ ≥ 0`, `U⁻¹ ≥ 0`,
//!   the off-diagonal factors are `≤ 0`, and `Y = F U⁻¹ ≥ 0`: every update
//!   below adds terms of one sign. No cancellation, so f32 storage with the
//!   product's blocked f32 summation keeps each entry's relative error near
//!   `(tile + N / tile) · 2⁻²⁴` per update; the condition number
//!   `≈ 1 / (1 − ρ)` amplifies it (tests: ρ up to 0.999 against f64).
//!
//! **The blocked algorithm** (blocks of `b` rows, `m` tiles of the product
//! and at least 256, [`block_tiles`]; `N` padded to whole blocks with
//! identity rows; `nt = N / b` block steps):
//! 1. right-looking LU: for each block `k`, the `b × b` diagonal block is
//!    read back and factored on the host in f64 (`L_kk`, `U_kk` and their
//!    inverses); then on the device the row panel `U_k,>k = L_kk⁻¹ M_k,>k`,
//!    the column panel `L_>k,k = M_>k,k U_kk⁻¹` and the trailing update
//!    `M_>k,>k −= L_>k,k U_k,>k` (`2/3 N³` flops);
//! 2. `Y = F U⁻¹`, left to right: `Y_:,k = F_:,k U_kk⁻¹`, then
//!    `F_:,>k −= Y_:,k U_k,>k` (`N³`);
//! 3. `X = Y L⁻¹`, right to left: `X_:,k = Y_:,k L_kk⁻¹`, then
//!    `Y_:,<k −= X_:,k L_k,<k` (`N³`).
//!
//! `8/3 N³` flops per channel in all, against about `2 log₂(bounces)` full
//! products (`2 N³` each) for doubling: 17 products at spectral radius 0.9,
//! 31 at 0.999. Every step is one call of the transfer stage's GEMM kernel
//! on sub-matrices ([`Gemm::product_at`]); the panels are multiplied in
//! place, one tile row or column per launch in an order that never reads
//! what the same launch writes (`triangular`). The host touches only the
//! `b × b` diagonal blocks.

use crate::error::BakeError;
use crate::gemm::{At, Gemm, GemmRun};

/// Errors name the transfer stage, which this solve is part of.
const STAGE: &str = "transfer";

/// What the solve of one channel did.
#[derive(Clone, Copy, Debug, Default)]
pub struct SolveRun {
    /// Product launches, tile products, device seconds and GFLOP.
    pub launches: u32,
    pub tile_products: u64,
    pub seconds: f64,
    pub gflop: f64,
}
use crate::compute::Access;
use opencl3::memory::Buffer;

/// Tiles per block step for the product's tile `ts`: blocks of at least
/// 256 rows, so that each update runs over at least 256 terms of K and the
/// trailing matrix is read and written half as often as with 128-row
/// blocks (PoCL's tile on AVX2 is 128).
pub fn block_tiles(ts: usize) -> usize {
    256usize.div_ceil(ts.max(1)).max(1)
}

/// Device launches the solve takes for an `n × n` system with the
/// product's tile `ts` (progress).
pub fn launches_for(n: usize, ts: usize) -> u64 {
    let m = block_tiles(ts);
    launches(n.div_ceil(m * ts).max(1), m)
}

/// Device launches the solve takes for `nt` block steps of `m` tiles.
pub fn launches(nt: usize, m: usize) -> u64 {
    // LU: row and column panels (m launches each) and the trailing update
    // per step but the last; forward and backward: a panel per step and an
    // update per step but one.
    let nt = nt.max(1);
    ((2 * m + 1) * (nt - 1) + 2 * m * nt + 2 * (nt - 1)) as u64
}

/// `T_∞` for colour channel `channel` with albedos `rho` (row-major
/// `n × n` `f`, the result likewise); `spectral_bound` (`max_i ρ_i Σ_j
/// F_ij`) is named in errors. `tick()` is called after every device launch.
pub fn lu_channel(
    g: &Gemm,
    f: &[f32],
    n: usize,
    rho: &[f32],
    channel: usize,
    spectral_bound: f64,
    tick: &mut dyn FnMut(),
) -> Result<(Vec<f32>, SolveRun), BakeError> {
    let name = ["R", "G", "B"][channel];
    let mut cs = SolveRun::default();
    // Block steps of `m` tiles of the product ([`block_tiles`]).
    let m = block_tiles(g.config().tile);
    let b = m * g.config().tile;
    let np = n.div_ceil(b).max(1) * b;
    let nt = np / b;
    g.gpu().check_total(STAGE, 2 * 4 * (np as u64).pow(2))?;
    // M = I − diag(ρ) F and F, padded to whole blocks (M with identity
    // rows and columns, F with zeros).
    let mut mm = vec![0.0f32; np * np];
    let mut fp = vec![0.0f32; np * np];
    for i in 0..np {
        if i < n {
            let r = rho[i] as f64;
            for j in 0..n {
                mm[i * np + j] = (-(r * f[i * n + j] as f64)) as f32;
            }
            mm[i * np + i] = (1.0 - r * f[i * n + i] as f64) as f32;
            fp[i * np..i * np + n].copy_from_slice(&f[i * n..(i + 1) * n]);
        } else {
            mm[i * np + i] = 1.0;
        }
    }
    let (dm, _) = g.upload("M = I - diag(rho) F", np, &mm)?;
    drop(mm);
    let (dx, _) = g.upload("F, then Y, then T", np, &fp)?;
    drop(fp);
    let mut account = |run: GemmRun, what: &str| -> Result<(), BakeError> {
        cs.launches += 1;
        cs.tile_products += run.tile_products;
        cs.seconds += run.seconds;
        cs.gflop += run.flops * 1e-9;
        tick();
        if run.nonfinite() {
            return Err(BakeError::Numeric {
                stage: STAGE,
                detail: format!(
                    "a non-finite value appeared in channel {name} at {what} of the LU solve \
                     (spectral bound max_i rho_i sum_j F_ij = {spectral_bound:.6})"
                ),
            });
        }
        Ok(())
    };
    let upload = |what: &str, v: &[f32]| g.gpu().upload(what, v, Access::ReadOnly);
    // Sizes below are in tiles of the product: a block is m × m tiles.
    let mut linv: Vec<Vec<f32>> = Vec::with_capacity(nt);
    let mut uinv: Vec<Vec<f32>> = Vec::with_capacity(nt);
    // 1. LU.
    for k in 0..nt {
        let kb = k * b;
        let d = g.read_block(&dm, kb, kb, b, b)?;
        let (l, u) = diagonal_inverses(&d, b).map_err(|(r, p)| BakeError::Numeric {
            stage: STAGE,
            detail: format!(
                "channel {name}: pivot {p:e} at patch {} of the LU factorisation of \
                 I - diag(rho) F: the system is not diagonally dominant (form-factor row sums \
                 above 1?)",
                kb + r
            ),
        })?;
        let rest = (nt - k - 1) * m;
        if rest > 0 {
            let lb = upload("L_kk^-1", &l)?;
            let ub = upload("U_kk^-1", &u)?;
            let (row, col, trail) = (dm.at(kb, kb + b), dm.at(kb + b, kb), dm.at(kb + b, kb + b));
            for run in triangular(g, Side::LeftLower, &lb, row, rest, m)? {
                account(run, &format!("row panel {k}"))?;
            }
            for run in triangular(g, Side::RightUpper, &ub, col, rest, m)? {
                account(run, &format!("column panel {k}"))?;
            }
            let run = g.product_at(col, row, trail, rest, rest, m, -1.0, true)?;
            account(run, &format!("trailing update {k}"))?;
        }
        linv.push(l);
        uinv.push(u);
    }
    let rows = nt * m;
    // 2. Y = F U⁻¹, left to right.
    for (k, u) in uinv.iter().enumerate() {
        let kb = k * b;
        let ub = upload("U_kk^-1", u)?;
        let panel = dx.at(0, kb);
        for run in triangular(g, Side::RightUpper, &ub, panel, rows, m)? {
            account(run, &format!("forward panel {k}"))?;
        }
        let rest = (nt - k - 1) * m;
        if rest > 0 {
            let run = g.product_at(
                panel,
                dm.at(kb, kb + b),
                dx.at(0, kb + b),
                rows,
                rest,
                m,
                -1.0,
                true,
            )?;
            account(run, &format!("forward update {k}"))?;
        }
    }
    // 3. X = Y L⁻¹, right to left.
    for (k, l) in linv.iter().enumerate().rev() {
        let kb = k * b;
        let lb = upload("L_kk^-1", l)?;
        let panel = dx.at(0, kb);
        for run in triangular(g, Side::RightLower, &lb, panel, rows, m)? {
            account(run, &format!("backward panel {k}"))?;
        }
        if k > 0 {
            let run = g.product_at(panel, dm.at(kb, 0), dx.at(0, 0), rows, k * m, m, -1.0, true)?;
            account(run, &format!("backward update {k}"))?;
        }
    }
    let all = g.download("T", &dx)?;
    let mut t = Vec::with_capacity(n * n);
    for i in 0..n {
        t.extend_from_slice(&all[i * np..i * np + n]);
    }
    drop(all);
    if let Some(e) = t.iter().position(|x| !x.is_finite()) {
        return Err(BakeError::Numeric {
            stage: STAGE,
            detail: format!("non-finite T entry {e} in channel {name} after the LU solve"),
        });
    }
    Ok((t, cs))
}

/// Which side and triangle a block inverse multiplies a panel from.
#[derive(Clone, Copy, PartialEq)]
enum Side {
    /// `P ← L⁻¹ P` (a row panel; `L⁻¹` lower triangular).
    LeftLower,
    /// `P ← P U⁻¹` (a column panel; `U⁻¹` upper triangular).
    RightUpper,
    /// `P ← P L⁻¹` (a column panel; `L⁻¹` lower triangular).
    RightLower,
}

/// `at` moved by `rows` and `cols` elements.
fn shifted(at: At<'_>, rows: usize, cols: usize) -> At<'_> {
    At {
        offset: at.offset + rows * at.pitch + cols,
        ..at
    }
}

/// The panel `p` (`extent` tiles long across the block, `m × m` tiles the
/// block) times the triangular block inverse `inv` (`m·ts` square, pitch
/// `m·ts`), in place, in `m` launches of one tile row or column each. The
/// order makes it safe: a launch writes one tile row (column) of the panel
/// and reads only rows (columns) that no earlier launch wrote — for
/// `L⁻¹ P`, row `i` needs rows `≤ i`, so rows go from the last to the
/// first; for `P U⁻¹` column `j` needs columns `≤ j` (last to first); for
/// `P L⁻¹` columns `≥ j` (first to last). Within a launch every work-group
/// reads the tile it writes only before its epilogue, and no tile another
/// work-group of the launch writes.
fn triangular(
    g: &Gemm,
    side: Side,
    inv: &Buffer<f32>,
    p: At<'_>,
    extent: usize,
    m: usize,
) -> Result<Vec<GemmRun>, BakeError> {
    let ts = g.config().tile;
    let b = m * ts;
    let inv = At {
        data: inv,
        offset: 0,
        pitch: b,
    };
    let mut runs = Vec::with_capacity(m);
    let order: Vec<usize> = match side {
        Side::LeftLower | Side::RightUpper => (0..m).rev().collect(),
        Side::RightLower => (0..m).collect(),
    };
    for i in order {
        let o = i * ts;
        runs.push(match side {
            Side::LeftLower => g.product_at(
                shifted(inv, o, 0),
                p,
                shifted(p, o, 0),
                1,
                extent,
                i + 1,
                1.0,
                false,
            )?,
            Side::RightUpper => g.product_at(
                p,
                shifted(inv, 0, o),
                shifted(p, 0, o),
                extent,
                1,
                i + 1,
                1.0,
                false,
            )?,
            Side::RightLower => g.product_at(
                shifted(p, 0, o),
                shifted(inv, o, o),
                shifted(p, 0, o),
                extent,
                1,
                m - i,
                1.0,
                false,
            )?,
        });
    }
    Ok(runs)
}

/// LU of the `b × b` row-major block `d` without pivoting, in f64, and the
/// inverses of its factors as f32: (`L⁻¹` with unit diagonal, `U⁻¹`).
/// `Err((row, pivot))` when a pivot is not positive and finite (`M` is then
/// not an M-matrix).
pub fn diagonal_inverses(d: &[f32], b: usize) -> Result<(Vec<f32>, Vec<f32>), (usize, f64)> {
    let mut a: Vec<f64> = d.iter().map(|&x| x as f64).collect();
    for k in 0..b {
        let p = a[k * b + k];
        if !(p > 0.0 && p.is_finite()) {
            return Err((k, p));
        }
        for i in k + 1..b {
            let l = a[i * b + k] / p;
            a[i * b + k] = l;
            if l != 0.0 {
                for j in k + 1..b {
                    a[i * b + j] -= l * a[k * b + j];
                }
            }
        }
    }
    // L⁻¹: solve L X = I, row by row (unit diagonal).
    let mut li = vec![0.0f64; b * b];
    for i in 0..b {
        li[i * b + i] = 1.0;
        for k in 0..i {
            let l = a[i * b + k];
            if l != 0.0 {
                for j in 0..=k {
                    li[i * b + j] -= l * li[k * b + j];
                }
            }
        }
    }
    // U⁻¹: solve U X = I, bottom row first.
    let mut ui = vec![0.0f64; b * b];
    for i in (0..b).rev() {
        let p = a[i * b + i];
        ui[i * b + i] = 1.0;
        for k in i + 1..b {
            let u = a[i * b + k];
            if u != 0.0 {
                for j in k..b {
                    ui[i * b + j] -= u * ui[k * b + j];
                }
            }
        }
        for j in i..b {
            ui[i * b + j] /= p;
        }
    }
    let f32s = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
    Ok((f32s(li), f32s(ui)))
}

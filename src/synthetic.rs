//! Seeded synthetic inputs with the structure of real ones, for tests,
//! benchmarks and reports when no scene is at hand: one module for every
//! fixture (the codec's synthetic room and the transfer stage's synthetic
//! form factors).
//!
//! ## A synthetic room
//!
//! A closed room of `m × m` patches per wall (a voxelized box: wall patches
//! in the boundary voxel layer, facing inwards) with a Cornell-box palette,
//! optionally a box of `b³` voxels in the middle with outward patches, in
//! the voxelizer's order (voxel key, then direction). Form factors are the
//! point-to-area approximation `F_ij = max(0, cos θ_i) max(0, cos θ_j)
//! A_j / (π r²)` without visibility, each row scaled down to a sum of 1 when
//! above (the approximation overestimates between adjacent patches), so
//! `F` keeps the invariants that matter here (non-negative, exact zeros
//! between coplanar patches, row sums ≤ 1). `T_∞ = F (I − diag(ρ) F)^{-1}`
//! per channel, solved in f64 with faer.
//!
//! ## Synthetic form factors
//!
//! Synthetic form factors with the invariants of real ones (non-negative,
//! zero diagonal, reciprocity `A_i F_ij = A_j F_ji`, row sums ≤ 1 or = 1),
//! seeded, for tests and benchmarks.

use crate::core::patch::{Direction, Patch};
use faer::linalg::solvers::Solve as _;
use rayon::prelude::*;

/// The seeded generator of the synthetic inputs.
pub use crate::core::math::SplitMix64 as Rng;

/// The Cornell box's wall albedos: the −x wall red, the +x wall green,
/// the rest white.
fn wall_albedo(facing: Direction) -> [f64; 3] {
    match facing {
        Direction::PosX => [0.63, 0.065, 0.05],
        Direction::NegX => [0.14, 0.45, 0.09],
        _ => [0.7, 0.7, 0.7],
    }
}

/// The room's patches (module doc); the room is the unit cube, `m`
/// voxels per edge; `b` (0: none) the edge of the central box in voxels.
pub fn room(m: usize, b: usize) -> Vec<Patch> {
    assert!(m >= 2 && b + 2 <= m);
    let size = 1.0 / m as f64;
    let mut out: Vec<(u64, Patch)> = Vec::new();
    let lo_box = (m - b) / 2;
    for z in 0..m {
        for y in 0..m {
            for x in 0..m {
                let v = [x, y, z];
                for d in Direction::ALL {
                    let a = d.axis();
                    // Walls: the boundary layer, facing inwards.
                    let wall = (v[a] == 0 && d.sign() > 0) || (v[a] == m - 1 && d.sign() < 0);
                    // The box: its boundary voxels, facing outwards.
                    let inside = |k: usize| k >= lo_box && k < lo_box + b;
                    let in_box = b > 0 && v.iter().all(|&k| inside(k));
                    let box_face = in_box
                        && ((d.sign() > 0 && v[a] == lo_box + b - 1)
                            || (d.sign() < 0 && v[a] == lo_box));
                    if !(wall || box_face) {
                        continue;
                    }
                    let normal = d.vector();
                    // The face of the voxel the patch looks out of.
                    let mut centre = [0.0; 3];
                    for k in 0..3 {
                        centre[k] = (v[k] as f64 + 0.5) * size;
                    }
                    centre[a] += 0.5 * size * d.sign() as f64;
                    let albedo = if wall {
                        wall_albedo(d)
                    } else {
                        [0.7, 0.7, 0.7]
                    };
                    let key = (x + m * (y + m * z)) as u64 * 6 + d as u64;
                    out.push((
                        key,
                        Patch {
                            centre,
                            normal,
                            area: size * size,
                            albedo,
                            emission: [0.0; 3],
                            voxel: [x as u32, y as u32, z as u32],
                            direction: d,
                        },
                    ));
                }
            }
        }
    }
    out.sort_by_key(|p| p.0);
    out.into_iter().map(|p| p.1).collect()
}

/// Point-to-area form factors without visibility, rows scaled to sum
/// ≤ 1 (module doc). Row-major n × n.
pub fn form_factors(patches: &[Patch]) -> Vec<f32> {
    let n = patches.len();
    let mut f = vec![0.0f32; n * n];
    f.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
        let p = &patches[i];
        let mut vals = vec![0.0f64; n];
        for (j, q) in patches.iter().enumerate() {
            if i == j {
                continue;
            }
            let d: [f64; 3] = std::array::from_fn(|k| q.centre[k] - p.centre[k]);
            let r2: f64 = d.iter().map(|x| x * x).sum();
            if r2 <= 0.0 {
                continue;
            }
            let r = r2.sqrt();
            let ci: f64 = (0..3).map(|k| p.normal[k] * d[k]).sum::<f64>() / r;
            let cj: f64 = -(0..3).map(|k| q.normal[k] * d[k]).sum::<f64>() / r;
            if ci > 0.0 && cj > 0.0 {
                vals[j] = ci * cj * q.area / (std::f64::consts::PI * r2);
            }
        }
        let sum: f64 = vals.iter().sum();
        let s = if sum > 1.0 { 1.0 / sum } else { 1.0 };
        for (o, v) in row.iter_mut().zip(vals) {
            *o = (v * s) as f32;
        }
    });
    f
}

/// `T_∞ = F (I − diag(ρ) F)^{-1}` in f64 (faer LU), rounded to f32.
pub fn transfer(f: &[f32], n: usize, rho: &[f64]) -> Vec<f32> {
    let fm = faer::Mat::<f64>::from_fn(n, n, |i, j| f[i * n + j] as f64);
    let m = faer::Mat::<f64>::from_fn(n, n, |i, j| {
        f64::from(i == j) - rho[i] * f[i * n + j] as f64
    });
    let t = m.partial_piv_lu().rsolve(fm.as_ref());
    (0..n * n).map(|k| t[(k / n, k % n)] as f32).collect()
}

/// The three channels of `T_∞` for the patches' albedos.
pub fn transfer_rgb(patches: &[Patch], f: &[f32]) -> [Vec<f32>; 3] {
    let n = patches.len();
    std::array::from_fn(|c| {
        let rho: Vec<f64> = patches.iter().map(|p| p.albedo[c]).collect();
        transfer(f, n, &rho)
    })
}

/// `count` seeded point lights inside the room (positions uniform in
/// the middle 80 % of the unit cube, RGB intensities in [0.5, 1]), as
/// `B0 = ρ ∘ D` with `D_j = I max(0, cos θ_j) / r²` (no shadows).
pub fn point_lights(patches: &[Patch], count: usize, seed: u64) -> Vec<[Vec<f32>; 3]> {
    let mut rng = Rng(seed);
    (0..count)
        .map(|_| {
            let pos: [f64; 3] = std::array::from_fn(|_| 0.1 + 0.8 * rng.uniform());
            let power: [f64; 3] = std::array::from_fn(|_| 0.5 + 0.5 * rng.uniform());
            std::array::from_fn(|c| {
                patches
                    .iter()
                    .map(|p| {
                        let d: [f64; 3] = std::array::from_fn(|k| pos[k] - p.centre[k]);
                        let r2: f64 = d.iter().map(|x| x * x).sum::<f64>().max(1e-6);
                        let cos = (0..3).map(|k| p.normal[k] * d[k]).sum::<f64>() / r2.sqrt();
                        (p.albedo[c] * power[c] * cos.max(0.0) / r2) as f32
                    })
                    .collect()
            })
        })
        .collect()
}
/// Form factors and the patch areas they are reciprocal with.
pub struct Synthetic {
    pub n: usize,
    /// Row-major `n × n`.
    pub f: Vec<f32>,
    pub area: Vec<f64>,
}

/// A random symmetric non-negative `G` with zero diagonal (entries
/// `u³`, u uniform, so that magnitudes spread over decades like real
/// form factors) and areas in [0.5, 2).
fn random_g(n: usize, rng: &mut Rng) -> (Vec<f64>, Vec<f64>) {
    let mut g = vec![0.0f64; n * n];
    for i in 0..n {
        for j in i + 1..n {
            let v = rng.uniform().powi(3);
            g[i * n + j] = v;
            g[j * n + i] = v;
        }
    }
    let area = (0..n).map(|_| 0.5 + 1.5 * rng.uniform()).collect();
    (g, area)
}

/// An open environment: `F_ij = c G_ij / A_i` with `c` such that the
/// largest row sum is `max_row_sum`.
pub fn open(n: usize, seed: u64, max_row_sum: f64) -> Synthetic {
    let mut rng = Rng::new(seed);
    let (g, area) = random_g(n, &mut rng);
    let max = (0..n)
        .map(|i| g[i * n..(i + 1) * n].iter().sum::<f64>() / area[i])
        .fold(0.0, f64::max);
    let c = if max > 0.0 { max_row_sum / max } else { 0.0 };
    let f = (0..n * n)
        .map(|e| (c * g[e] / area[e / n]) as f32)
        .collect();
    Synthetic { n, f, area }
}

/// A closed environment: rows sum to 1 (to f64 precision before the
/// rounding to f32), reciprocity kept. `G` is scaled symmetrically,
/// `G' = X G X`, so that `G' 1 = A` (symmetric Sinkhorn iteration
/// `x_i ← sqrt(x_i A_i / (G x)_i)`; Knight, Ruiz & Uçar, "A symmetry
/// preserving algorithm for matrix scaling", SIAM J. Matrix Anal. Appl.
/// 35(3), 2014), then `F_ij = G'_ij / A_i`.
pub fn closed(n: usize, seed: u64) -> Synthetic {
    assert!(n >= 3, "a closed environment needs at least 3 patches");
    let mut rng = Rng::new(seed);
    let (g, area) = random_g(n, &mut rng);
    let mut x = vec![1.0f64; n];
    for _ in 0..10_000 {
        let gx: Vec<f64> = (0..n)
            .map(|i| {
                g[i * n..(i + 1) * n]
                    .iter()
                    .zip(&x)
                    .map(|(a, b)| a * b)
                    .sum()
            })
            .collect();
        let worst = (0..n)
            .map(|i| (x[i] * gx[i] / area[i] - 1.0).abs())
            .fold(0.0, f64::max);
        if worst < 1e-14 {
            break;
        }
        for i in 0..n {
            x[i] = (x[i] * area[i] / gx[i]).sqrt();
        }
    }
    let f = (0..n * n)
        .map(|e| {
            let (i, j) = (e / n, e % n);
            (x[i] * g[e] * x[j] / area[i]) as f32
        })
        .collect();
    Synthetic { n, f, area }
}

/// Closed rooms that do not see each other: a block-diagonal `F` with
/// one [`closed`] block per room.
pub fn rooms(sizes: &[usize], seed: u64) -> Synthetic {
    let n: usize = sizes.iter().sum();
    let mut f = vec![0.0f32; n * n];
    let mut area = Vec::with_capacity(n);
    let mut o = 0;
    for (r, &m) in sizes.iter().enumerate() {
        let room = closed(m, seed.wrapping_add(r as u64 * 7919));
        for i in 0..m {
            f[(o + i) * n + o..(o + i) * n + o + m].copy_from_slice(&room.f[i * m..(i + 1) * m]);
        }
        area.extend(room.area);
        o += m;
    }
    Synthetic { n, f, area }
}

/// Grey albedos uniform in `[lo, hi)`.
pub fn albedo(n: usize, seed: u64, lo: f64, hi: f64) -> Vec<[f32; 3]> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let a = (lo + (hi - lo) * rng.uniform()) as f32;
            [a; 3]
        })
        .collect()
}

/// Coloured albedos, each channel uniform in `[0, hi)`.
pub fn colour_albedo(n: usize, seed: u64, hi: f64) -> Vec<[f32; 3]> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| std::array::from_fn(|_| (hi * rng.uniform()) as f32))
        .collect()
}

//! Sky cells: the sphere of directions cut into `SIDE × SIDE` cells of an
//! octahedral map (Cigolle et al., "A Survey of Efficient Representations
//! for Independent Unit Vectors", JCGT 2014, with `+y` up), the basis the
//! sky's radiance and the baked sky visibility meet in. A patch's
//! visibility is, per cell, the cosine-weighted solid angle of the cell
//! through which it sees out of the scene (`T_c = π/N` × the form-factor
//! rays that escaped through the cell); a sky is, per cell, its mean
//! radiance over the cell's solid angle (`L̄_c`); the sky's irradiance on
//! the patch is `D_sky = Σ_c L̄_c T_c`.
//!
//! Cells rather than spherical harmonics: a patch sees the sky through an
//! opening (a courtyard, a window) while the sky is brightest around its
//! sun, and the product of a sharp window and a peaked sky is what
//! low-order harmonics cannot carry. Measured at points of a floor under
//! a unit-box opening with Preetham's sun and sky (12 cases, brute force
//! on a 400 × 800 grid): band-2 harmonics err by up to 63 %, band 4 by
//! 35 %, cells of 8 × 8 by 12 %, of 16 × 16 by 2.5 %, of 32 × 32 by
//! 0.6 %. 16 × 16 (256 cells of about 0.049 sr, 12.7°) keeps the error a
//! few percent, a cell index a byte, and a patch's stored cells few (the
//! ones its opening spans). The error left is the sky's variation within
//! a cell where the opening's edge cuts it; a uniform sky is exact, an
//! unoccluded plane under it gets `π L` and a closed room 0.

/// Cells along each side of the octahedral map.
pub const SIDE: usize = 16;
/// Cells on the sphere.
pub const CELLS: usize = SIDE * SIDE;

/// The octahedral coordinates in [−1, 1]² of the direction `d` (need not
/// be unit): the upper hemisphere (`y ≥ 0`) maps to the inner diamond,
/// the lower one is folded onto the corners.
pub fn octahedral(d: [f64; 3]) -> (f64, f64) {
    let s = d[0].abs() + d[1].abs() + d[2].abs();
    if !(s > 0.0) {
        return (0.0, 0.0);
    }
    let (u, v) = (d[0] / s, d[2] / s);
    if d[1] >= 0.0 {
        (u, v)
    } else {
        (
            (1.0 - v.abs()) * if u >= 0.0 { 1.0 } else { -1.0 },
            (1.0 - u.abs()) * if v >= 0.0 { 1.0 } else { -1.0 },
        )
    }
}

/// The (not normalised) direction at octahedral coordinates `(u, v)`,
/// the inverse of [`octahedral`] up to length; its length `r` gives the
/// map's solid angle per unit area, `dω = du dv / r³` with `r = |q|` for
/// the point `q` on the octahedron `|x| + |y| + |z| = 1`.
pub fn direction(u: f64, v: f64) -> [f64; 3] {
    let y = 1.0 - u.abs() - v.abs();
    if y >= 0.0 {
        [u, y, v]
    } else {
        // Unfold the corner: |u'| = 1 − |v|, |v'| = 1 − |u|.
        let su = if u >= 0.0 { 1.0 } else { -1.0 };
        let sv = if v >= 0.0 { 1.0 } else { -1.0 };
        [(1.0 - v.abs()) * su, y, (1.0 - u.abs()) * sv]
    }
}

/// The cell of direction `d`.
pub fn cell(d: [f64; 3]) -> usize {
    let (u, v) = octahedral(d);
    let i = (((u + 1.0) * 0.5 * SIDE as f64) as usize).min(SIDE - 1);
    let j = (((v + 1.0) * 0.5 * SIDE as f64) as usize).min(SIDE - 1);
    i * SIDE + j
}

/// Sub-samples per cell side in [`mean_radiance`]: 16 × 16 points a cell
/// (65,536 directions a sky, about 5 ms for the sun and sky), the
/// midpoint rule weighted by the map's solid angle.
pub const SUB: usize = 16;

/// Each cell's mean of `f` over its solid angle (unit directions given to
/// `f`), by the weighted midpoint rule on `SUB × SUB` points a cell.
pub fn mean_radiance(f: impl Fn([f64; 3]) -> [f64; 3] + Sync) -> Vec<[f64; 3]> {
    use rayon::prelude::*;
    let n = SIDE * SUB;
    (0..CELLS)
        .into_par_iter()
        .map(|c| {
            let (ci, cj) = (c / SIDE, c % SIDE);
            let (mut sum, mut w) = ([0.0; 3], 0.0);
            for a in 0..SUB {
                for b in 0..SUB {
                    let u = ((ci * SUB + a) as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                    let v = ((cj * SUB + b) as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                    let q = direction(u, v);
                    let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                    let dw = 1.0 / (r * r * r);
                    let l = f(q.map(|x| x / r));
                    for k in 0..3 {
                        sum[k] += l[k] * dw;
                    }
                    w += dw;
                }
            }
            sum.map(|s| s / w)
        })
        .collect()
}

/// Irradiance from per-cell visibility `(cell, T_c)` and per-cell mean
/// radiance: `Σ L̄_c T_c` per channel.
pub fn irradiance(
    radiance: &[[f64; 3]],
    visibility: impl Iterator<Item = (usize, f64)>,
) -> [f64; 3] {
    let mut e = [0.0; 3];
    for (c, t) in visibility {
        for k in 0..3 {
            e[k] += radiance[c][k] * t;
        }
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The map and its inverse agree, every cell is reached, and the
    /// solid angles sum to 4π (the `1/r³` weights: 4π to the midpoint
    /// rule's error on 256 × 256 points).
    #[test]
    fn the_map_inverts_and_covers_the_sphere() {
        for k in 0..2000 {
            let y = 1.0 - 2.0 * (k as f64 + 0.5) / 2000.0;
            let phi = k as f64 * 2.399_963;
            let r = (1.0 - y * y).sqrt();
            let d = [r * phi.cos(), y, r * phi.sin()];
            let (u, v) = octahedral(d);
            let q = direction(u, v);
            let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            for a in 0..3 {
                assert!((q[a] / n - d[a]).abs() < 1e-12, "{d:?} {q:?}");
            }
        }
        let n = SIDE * SUB;
        let (mut total, mut seen) = (0.0, vec![false; CELLS]);
        for a in 0..n {
            for b in 0..n {
                let u = (a as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                let v = (b as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                let q = direction(u, v);
                let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                total += (2.0 / n as f64).powi(2) / (r * r * r);
                seen[cell(q)] = true;
            }
        }
        assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-3, "{total}");
        assert!(seen.iter().all(|&s| s));
    }

    /// A constant is its own mean in every cell; a sky bright only above
    /// the horizon leaves the lower cells dark.
    #[test]
    fn means_are_means() {
        let m = mean_radiance(|_| [1.0, 2.0, 3.0]);
        for l in &m {
            for k in 0..3 {
                assert!((l[k] - [1.0, 2.0, 3.0][k]).abs() < 1e-12);
            }
        }
        let m = mean_radiance(|d| if d[1] > 0.0 { [1.0; 3] } else { [0.0; 3] });
        assert_eq!(m[cell([0.0, 1.0, 0.0])], [1.0; 3]);
        assert_eq!(m[cell([0.1, -1.0, 0.2])], [0.0; 3]);
    }
}

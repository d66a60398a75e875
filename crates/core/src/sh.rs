//! Real spherical harmonics up to band 2 (9 coefficients), for smooth
//! functions of direction such as a probe's irradiance (issue 46). A
//! point's irradiance under a radiance `L` is the dot product of
//! `L_lm = ∫ L(ω) Y_lm(ω) dω` and the point's transfer
//! `T_lm = ∫ V(ω) max(0, n·ω) Y_lm(ω) dω` (precomputed radiance transfer,
//! Sloan, Kautz and Snyder 2002): exact for a radiance within bands 0–2,
//! and for any where nothing is occluded (the cosine lobe's energy is 99 %
//! in bands 0–2, Ramamoorthi and Hanrahan 2001).
//!
//! The sky used these first and no longer does: where visibility cuts a
//! window out of a peaked sky the product needs far higher bands (22 % off
//! on a floor under an opening with the sun in view); the sky's basis is
//! its cells (`crates/core/src/sky/cells.rs`, where the errors are
//! measured).

/// Coefficients per colour channel.
pub const COEFFICIENTS: usize = 9;

/// The basis at the unit direction `d` (x, y, z), in the order
/// `Y_00, Y_1-1, Y_10, Y_11, Y_2-2, Y_2-1, Y_20, Y_21, Y_22` with `y` up
/// (the constants of Ramamoorthi and Hanrahan 2001, their `z` our `y`).
pub fn basis(d: [f64; 3]) -> [f64; COEFFICIENTS] {
    let [x, y, z] = d;
    [
        0.282_094_791_773_878_14,
        0.488_602_511_902_919_9 * z,
        0.488_602_511_902_919_9 * y,
        0.488_602_511_902_919_9 * x,
        1.092_548_430_592_079_2 * x * z,
        1.092_548_430_592_079_2 * z * y,
        0.315_391_565_252_520_05 * (3.0 * y * y - 1.0),
        1.092_548_430_592_079_2 * x * y,
        0.546_274_215_296_039_6 * (x * x - z * z),
    ]
}

/// `∫ f(ω) Y_lm(ω) dω` over the sphere per channel: Gauss–Legendre in
/// `y = cos θ` on `rings` nodes times the midpoint rule in `φ` on `2 rings`
/// cells, exact for the basis products (polynomials of degree ≤ 4 in `y`,
/// trigonometric of order ≤ 4 in `φ`) from 3 rings on, and converging
/// fast for a smooth `f` (a kink, such as a gradient sky's horizon, costs
/// `O(rings⁻²)`).
pub fn project(f: impl Fn([f64; 3]) -> [f64; 3], rings: usize) -> [[f64; 3]; COEFFICIENTS] {
    let rings = rings.max(3);
    let cells = 2 * rings;
    let dphi = 2.0 * std::f64::consts::PI / cells as f64;
    let mut out = [[0.0; 3]; COEFFICIENTS];
    for (y, wy) in gauss_legendre(rings) {
        let s = (1.0 - y * y).max(0.0).sqrt();
        for c in 0..cells {
            let phi = dphi * (c as f64 + 0.5);
            let d = [s * phi.cos(), y, s * phi.sin()];
            let v = f(d);
            let w = wy * dphi;
            for (o, b) in out.iter_mut().zip(basis(d)) {
                for k in 0..3 {
                    o[k] += w * b * v[k];
                }
            }
        }
    }
    out
}

/// The `n` Gauss–Legendre nodes and weights on [−1, 1]: Newton's method
/// on the Legendre polynomial from Chebyshev guesses (Numerical Recipes,
/// `gauleg`), to 1e-15.
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                // P_n(x) and P_n'(x) by the three-term recurrence.
                let (mut p0, mut p1) = (1.0f64, x);
                for k in 2..=n {
                    let k = k as f64;
                    (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
                }
                let p = if n == 0 { 1.0 } else { p1 };
                let pm1 = if n == 1 { 1.0 } else { p0 };
                dp = n as f64 * (x * p - pm1) / (x * x - 1.0);
                let dx = p / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// `Σ_lm L_lm T_lm` per channel: the irradiance of a point with transfer
/// `t` under a sky of coefficients `l`.
pub fn irradiance(l: &[[f64; 3]; COEFFICIENTS], t: &[f32; COEFFICIENTS]) -> [f64; 3] {
    let mut e = [0.0; 3];
    for (lc, &tc) in l.iter().zip(t) {
        for k in 0..3 {
            e[k] += lc[k] * f64::from(tc);
        }
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The basis is orthonormal: the projection of each basis function is
    /// its unit vector (to the quadrature's rounding).
    #[test]
    fn the_basis_is_orthonormal() {
        for i in 0..COEFFICIENTS {
            let p = project(|d| [basis(d)[i]; 3], 4);
            for (j, c) in p.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((c[0] - want).abs() < 1e-12, "<Y{i}, Y{j}> = {}", c[0]);
            }
        }
    }

    /// A uniform sky of radiance 1 over an unoccluded upward plane: its
    /// transfer is `π Y_00` in band 0 and `2π/3 · 0.4886` in `Y_10`
    /// (the clamped cosine's projection), and the irradiance is π.
    #[test]
    fn an_open_plane_under_a_uniform_sky_gets_pi() {
        let l = project(|_| [1.0; 3], 64);
        // The clamped cosine has a kink at the horizon: 512 rings.
        let t = project(|d| [d[1].max(0.0); 3], 512).map(|c| c[0] as f32);
        let e = irradiance(&l, &t);
        assert!((e[0] - std::f64::consts::PI).abs() < 1e-5, "{e:?}");
        assert!((f64::from(t[0]) - std::f64::consts::PI * basis([0.0, 1.0, 0.0])[0]).abs() < 1e-4);
    }
}

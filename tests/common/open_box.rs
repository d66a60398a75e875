//! The unit box `[0, 1]³` seen from inside, open at the top or not, and
//! what is known about it exactly: the view factor from a floor point to
//! the opening (the sky tests' oracle).

use super::Quad;
use radiosity::bakefile::baked::Baked;
use std::f64::consts::PI;

/// The inward faces of the unit box `[0, 1]³`, its top (+y) left open when
/// `open`.
pub fn unit_box(open: bool) -> Vec<Quad> {
    let mut quads = super::box_inside([0.0; 3], [1.0; 3], [0.6, 0.5, 0.4]);
    if open {
        quads.remove(3);
    }
    quads
}

/// The view factor from a point to a parallel rectangle at height `h`
/// whose corner is straight above it, of sides `a` and `b` (Howell's
/// catalogue, C-11 for a differential element):
/// `1/2π (X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²)))`.
pub fn corner_view_factor(a: f64, b: f64, h: f64) -> f64 {
    let (x, y) = (a / h, b / h);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

/// The view factor from the floor point (x, z) of the unit box to its
/// opening (the top, 1 above): four corner rectangles meeting above the
/// point.
pub fn to_opening(x: f64, z: f64) -> f64 {
    [(x, z), (1.0 - x, z), (x, 1.0 - z), (1.0 - x, 1.0 - z)]
        .iter()
        .map(|&(a, b)| corner_view_factor(a, b, 1.0))
        .sum()
}

/// The floor patches of a bake of the unit box: (index, their square's
/// centre x, z and half side).
pub fn floor_patches(baked: &Baked) -> Vec<(usize, f64, f64, f64)> {
    baked
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| p.normal[1] > 0.99 && p.centre[1].abs() < 1e-3)
        .map(|(i, p)| {
            (
                i,
                f64::from(p.centre[0]),
                f64::from(p.centre[2]),
                f64::from(p.half),
            )
        })
        .collect()
}

/// The mean of `f` over the square of centre (x, z) and half side `h`, by
/// the midpoint rule on 16 × 16 points.
pub fn mean_over(x: f64, z: f64, h: f64, f: impl Fn(f64, f64) -> f64) -> f64 {
    let k = 16;
    let mut s = 0.0;
    for a in 0..k {
        for b in 0..k {
            let px = x - h + 2.0 * h * (a as f64 + 0.5) / k as f64;
            let pz = z - h + 2.0 * h * (b as f64 + 0.5) / k as f64;
            s += f(px, pz);
        }
    }
    s / (k * k) as f64
}

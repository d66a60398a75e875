//! Planar convex polygons (the pieces of triangles in voxels, and their
//! parts): area and centroid, and area-stratified points. Shared by the
//! voxelizer, the cuts and the piece geometry of the later bake stages.

use crate::math::{cross, dot, sub};

/// Area and centroid of a planar polygon with unit normal `n`.
pub fn polygon_area_centroid(poly: &[[f64; 3]], n: [f64; 3]) -> (f64, [f64; 3]) {
    if poly.len() < 3 {
        return (0.0, poly.first().copied().unwrap_or([0.0; 3]));
    }
    let (mut a2, mut acc) = (0.0, [0.0; 3]);
    for i in 1..poly.len() - 1 {
        let s = dot(cross(sub(poly[i], poly[0]), sub(poly[i + 1], poly[0])), n);
        a2 += s;
        for q in 0..3 {
            acc[q] += s * (poly[0][q] + poly[i][q] + poly[i + 1][q]);
        }
    }
    if !(a2.abs() > 0.0) {
        return (0.0, poly[0]);
    }
    (0.5 * a2.abs(), acc.map(|x| x / (3.0 * a2)))
}

/// `count` points on a convex polygon, stratified by area: point `s` in
/// the fan triangle at the area quantile `(s + ½)/count`, placed there by
/// the R2 sequence (Roberts 2018) folded into the triangle. Empty for a
/// polygon without area.
pub fn stratified_points(poly: &[[f64; 3]], count: usize) -> Vec<[f64; 3]> {
    const R2: [f64; 2] = [0.754_877_666_246_692_7, 0.569_840_290_998_053_2];
    let mut fans: Vec<(usize, f64)> = Vec::new();
    let mut total = 0.0;
    for t in 1..poly.len().saturating_sub(1) {
        let a = 0.5 * crate::math::norm(cross(sub(poly[t], poly[0]), sub(poly[t + 1], poly[0])));
        if a > 0.0 {
            total += a;
            fans.push((t, total));
        }
    }
    if fans.is_empty() {
        return Vec::new();
    }
    (0..count)
        .map(|s| {
            let q = (s as f64 + 0.5) / count as f64 * total;
            let f = fans.partition_point(|x| x.1 < q).min(fans.len() - 1);
            let t = fans[f].0;
            let (mut u, mut v) = (
                (0.5 + R2[0] * s as f64).fract(),
                (0.5 + R2[1] * s as f64).fract(),
            );
            if u + v > 1.0 {
                u = 1.0 - u;
                v = 1.0 - v;
            }
            std::array::from_fn(|k| {
                poly[0][k] + u * (poly[t][k] - poly[0][k]) + v * (poly[t + 1][k] - poly[0][k])
            })
        })
        .collect()
}

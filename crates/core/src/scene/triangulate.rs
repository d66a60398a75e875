//! Triangles of an OBJ polygon face. `tobj` triangulates every polygon as a
//! fan from its first vertex, which is right only for polygons that are
//! convex (or star-shaped from that vertex): the floor of an L-shaped or
//! C-shaped room exported as one face, or a wall with a notch, gets
//! triangles outside the polygon, overlapping and wound backwards (a
//! C-shaped floor of area 7 loaded with area 11). The loader reads
//! polygons untriangulated and calls [`triangulate`]: convex polygons get
//! the same fan as before (so scenes that loaded right load bit for bit
//! the same), others are cut by ear clipping (Eberly, "Triangulation by
//! Ear Clipping", Geometric Tools 2002) in the plane of their Newell normal.

use crate::math::{cross, dot, sub};

/// Polygons with more vertices than this are fanned without trying ear
/// clipping (whose cost grows as the cube of the vertex count), and
/// counted as not triangulated.
pub const EAR_CLIPPING_MAX_VERTICES: usize = 4096;

/// How a polygon was triangulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Triangulation {
    /// Convex (within rounding): the fan from the first vertex.
    Fan,
    /// Not convex: ear clipping.
    EarClipped,
    /// Not convex, and ear clipping found no ear (a self-intersecting
    /// outline) or the polygon is too large: the fan, which may cover the
    /// wrong area.
    Failed,
}

/// Triangles (indices into `p`, in `p`'s winding) covering the polygon `p`
/// (its vertices in order, `p.len() >= 3`).
pub fn triangulate(p: &[[f64; 3]]) -> (Vec<[usize; 3]>, Triangulation) {
    let k = p.len();
    let fan = || (1..k - 1).map(|i| [0, i, i + 1]).collect::<Vec<_>>();
    if k <= 3 {
        return (fan(), Triangulation::Fan);
    }
    // Newell's normal (of the polygon's area, valid for non-planar and
    // non-convex outlines).
    let mut n = [0.0f64; 3];
    for i in 0..k {
        let (a, b) = (p[i], p[(i + 1) % k]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    if dot(n, n) == 0.0 {
        return (fan(), Triangulation::Fan);
    }
    // Convex when no corner turns against the normal, beyond rounding of
    // its edges' lengths (a straight run of vertices is convex).
    let convex = (0..k).all(|i| {
        let (a, b, c) = (p[(i + k - 1) % k], p[i], p[(i + 1) % k]);
        let (e1, e2) = (sub(b, a), sub(c, b));
        dot(cross(e1, e2), n) >= -1e-9 * dot(e1, e1).sqrt() * dot(e2, e2).sqrt() * dot(n, n).sqrt()
    });
    if convex {
        return (fan(), Triangulation::Fan);
    }
    if k > EAR_CLIPPING_MAX_VERTICES {
        return (fan(), Triangulation::Failed);
    }
    // Project onto the plane of the dominant axis of the normal, keeping
    // the winding counter-clockwise.
    let axis = (0..3)
        .max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
        .unwrap_or(2);
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let sign = if n[axis] >= 0.0 { 1.0 } else { -1.0 };
    let q: Vec<[f64; 2]> = p.iter().map(|x| [x[u], sign * x[v]]).collect();
    match ear_clip(&q) {
        Some(t) => (t, Triangulation::EarClipped),
        None => (fan(), Triangulation::Failed),
    }
}

/// Twice the signed area of the triangle `a b c` (positive when
/// counter-clockwise).
fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Ear clipping of the simple counter-clockwise polygon `q`; `None` when
/// no ear is left (the outline crosses itself).
fn ear_clip(q: &[[f64; 2]]) -> Option<Vec<[usize; 3]>> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for x in q {
        for a in 0..2 {
            lo[a] = lo[a].min(x[a]);
            hi[a] = hi[a].max(x[a]);
        }
    }
    let size2 = (hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2);
    // Areas below this are rounding (relative 1e-12 of the polygon's).
    let eps = 1e-12 * size2;
    let mut idx: Vec<usize> = (0..q.len()).collect();
    let mut out = Vec::with_capacity(q.len() - 2);
    while idx.len() > 3 {
        let m = idx.len();
        let ear = (0..m).find(|&i| {
            let (a, b, c) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
            if orient(q[a], q[b], q[c]) <= eps {
                return false;
            }
            // No other vertex inside or on the ear (a vertex at one of the
            // ear's corners, where the outline touches itself, does not
            // count).
            idx.iter().all(|&j| {
                if j == a || j == b || j == c || q[j] == q[a] || q[j] == q[b] || q[j] == q[c] {
                    return true;
                }
                let x = q[j];
                !(orient(q[a], q[b], x) >= -eps
                    && orient(q[b], q[c], x) >= -eps
                    && orient(q[c], q[a], x) >= -eps)
            })
        });
        match ear {
            Some(i) => {
                let (a, b, c) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
                out.push([a, b, c]);
                idx.remove(i);
            }
            None => {
                // A vertex on a straight run between its neighbours adds
                // no area: drop it and look again.
                let flat = (0..m).find(|&i| {
                    let (a, b, c) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
                    orient(q[a], q[b], q[c]).abs() <= eps
                })?;
                idx.remove(flat);
            }
        }
    }
    if idx.len() == 3 {
        out.push([idx[0], idx[1], idx[2]]);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Per triangle its area vector (half the cross product).
    fn areas(p: &[[f64; 3]], t: &[[usize; 3]]) -> Vec<[f64; 3]> {
        t.iter()
            .map(|&[a, b, c]| cross(sub(p[b], p[a]), sub(p[c], p[a])).map(|x| 0.5 * x))
            .collect()
    }

    #[test]
    fn convex_polygons_keep_the_fan_and_others_are_cut_into_their_area() {
        let square = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        assert_eq!(
            triangulate(&square),
            (vec![[0, 1, 2], [0, 2, 3]], Triangulation::Fan)
        );
        // A C shape of area 7 in the plane y = 0.5, both windings: 6
        // triangles whose areas add up to 7, all wound like the outline.
        let c2 = [
            (0.0, 0.0),
            (3.0, 0.0),
            (3.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (3.0, 2.0),
            (3.0, 3.0),
            (0.0, 3.0),
        ];
        for flip in [false, true] {
            let mut c: Vec<[f64; 3]> = c2.iter().map(|&(x, z)| [x, 0.5, z]).collect();
            if flip {
                c.reverse();
            }
            let (t, how) = triangulate(&c);
            assert_eq!(how, Triangulation::EarClipped);
            assert_eq!(t.len(), 6);
            let a = areas(&c, &t);
            let y: Vec<f64> = a.iter().map(|v| v[1]).collect();
            let total: f64 = y.iter().sum();
            assert!((total.abs() - 7.0).abs() < 1e-12, "area {total}");
            assert!(
                y.iter().all(|v| v * total > 0.0),
                "a triangle is wound backwards: {y:?}"
            );
        }
    }
}

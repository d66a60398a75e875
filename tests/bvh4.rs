//! The four-wide BVH of the shadow rays against the binary one it is built
//! from (`crates/core/src/bvh4.rs`): on generated scenes that are not kind
//! (lattice walls whose box planes rays start on and run along, slivers,
//! millimetre and kilometre scales far from the origin, a random soup), a
//! segment is blocked for one exactly when it is for the other and the
//! nearest hit lies at the same distance, on the AVX and the portable box
//! test alike, for single segments and for packets of eight (AVX-512);
//! and the four-box test agrees with the binary slab test, NaN cases
//! included.

use radiosity::core::bvh::{intersect, slab, Bvh, Node};
use radiosity::core::bvh4::{test4_portable, Bvh4, Node4};
use radiosity::core::math::SplitMix64;

/// A scene: positions and triangles.
type Soup = (Vec<[f32; 3]>, Vec<[u32; 3]>);

fn push_quad(s: &mut Soup, c: [f64; 3], u: [f64; 3], v: [f64; 3]) {
    let base = s.0.len() as u32;
    for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        s.0.push(std::array::from_fn(|k| (c[k] + a * u[k] + b * v[k]) as f32));
    }
    s.1.push([base, base + 1, base + 2]);
    s.1.push([base, base + 2, base + 3]);
}

/// Walls on an integer lattice: box planes at integers, so rays starting
/// at integer coordinates along an axis give `0 × ∞` in the slab test.
fn lattice(scale: f64, offset: f64) -> Soup {
    let mut s = (Vec::new(), Vec::new());
    for i in 0..6 {
        for j in 0..6 {
            let (x, z) = (i as f64 * 2.0, j as f64 * 2.0);
            let w = |p: [f64; 3]| p.map(|v| v * scale + offset);
            let h = scale;
            if (i + j) % 2 == 0 {
                push_quad(&mut s, w([x, 1.0, z]), [h, 0.0, 0.0], [0.0, h, 0.0]);
            }
            if (i * 3 + j) % 4 != 1 {
                push_quad(
                    &mut s,
                    w([x + 1.0, 0.0, z + 1.0]),
                    [h, 0.0, 0.0],
                    [0.0, 0.0, h],
                );
            }
            if (i + 2 * j) % 3 == 0 {
                push_quad(&mut s, w([x, 1.0, z + 1.0]), [0.0, 0.0, h], [0.0, h, 0.0]);
            }
        }
    }
    s
}

/// Long thin triangles (aspect up to 1e5) crossing each other, as a grid
/// cuts walls into slivers.
fn slivers(rng: &mut SplitMix64) -> Soup {
    let mut s = (Vec::new(), Vec::new());
    for _ in 0..600 {
        let a: [f64; 3] = std::array::from_fn(|_| rng.uniform() * 10.0);
        let dir: [f64; 3] = std::array::from_fn(|_| rng.uniform() - 0.5);
        let len = 1.0 + 5.0 * rng.uniform();
        let b: [f64; 3] = std::array::from_fn(|k| a[k] + dir[k] * len);
        let w = 10f64.powf(-5.0 + 4.0 * rng.uniform());
        let c: [f64; 3] = std::array::from_fn(|k| 0.5 * (a[k] + b[k]) + w * (rng.uniform() - 0.5));
        let base = s.0.len() as u32;
        for p in [a, b, c] {
            s.0.push(p.map(|v| v as f32));
        }
        s.1.push([base, base + 1, base + 2]);
    }
    s
}

/// Random triangles of every size in a cube of side `size` around `at`.
fn soup(rng: &mut SplitMix64, size: f64, at: f64) -> Soup {
    let mut s = (Vec::new(), Vec::new());
    for _ in 0..1500 {
        let c: [f64; 3] = std::array::from_fn(|_| at + size * rng.uniform());
        let r = size * 10f64.powf(-3.0 + 2.5 * rng.uniform());
        let base = s.0.len() as u32;
        for _ in 0..3 {
            s.0.push(std::array::from_fn(|k| {
                (c[k] + r * (rng.uniform() - 0.5)) as f32
            }));
        }
        s.1.push([base, base + 1, base + 2]);
    }
    s
}

/// Segments for `scene`: random ones, ones along the axes from lattice
/// points (when `lattice` is set), and ones aimed at vertices and edge
/// midpoints (grazing the widened triangle test).
fn segments(
    rng: &mut SplitMix64,
    scene: &Soup,
    lattice: Option<(f64, f64)>,
) -> Vec<([f64; 3], [f64; 3])> {
    let (lo, hi) = scene
        .0
        .iter()
        .fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
            (
                std::array::from_fn(|k| lo[k].min(p[k] as f64)),
                std::array::from_fn(|k| hi[k].max(p[k] as f64)),
            )
        });
    let ext: [f64; 3] = std::array::from_fn(|k| (hi[k] - lo[k]).max(1e-9));
    let inside = |rng: &mut SplitMix64| -> [f64; 3] {
        std::array::from_fn(|k| lo[k] - 0.1 * ext[k] + 1.2 * ext[k] * rng.uniform())
    };
    let mut out = Vec::new();
    for i in 0..6000 {
        let o = inside(rng);
        let d = match i % 4 {
            0 => {
                let e = inside(rng);
                std::array::from_fn(|k| e[k] - o[k])
            }
            1 => {
                // Towards a vertex or an edge's midpoint, sometimes beyond.
                let t = scene.1[(rng.next_u64() % scene.1.len() as u64) as usize];
                let a = scene.0[t[0] as usize].map(f64::from);
                let b = scene.0[t[1] as usize].map(f64::from);
                let p: [f64; 3] = if rng.uniform() < 0.5 {
                    a
                } else {
                    std::array::from_fn(|k| 0.5 * (a[k] + b[k]))
                };
                let s = if rng.uniform() < 0.5 { 1.0 } else { 1.5 };
                std::array::from_fn(|k| s * (p[k] - o[k]))
            }
            _ => {
                // Along an axis or in an axis plane (zero components).
                let mut d: [f64; 3] = std::array::from_fn(|k| (rng.uniform() - 0.5) * 2.0 * ext[k]);
                d[(rng.next_u64() % 3) as usize] = 0.0;
                if i % 4 == 3 {
                    d[(rng.next_u64() % 3) as usize] = 0.0;
                }
                d
            }
        };
        // From a lattice point (on box planes) for half of the lattice's.
        let o = match lattice {
            Some((scale, offset)) if i % 2 == 0 => {
                o.map(|v| ((v - offset) / scale).round() * scale + offset)
            }
            _ => o,
        };
        out.push((o, d));
    }
    out
}

/// Both traversals on every segment: the same blocked-or-not answer, and
/// the named blocker is one [`Bvh::hits_in_leaf`] confirms. Returns how
/// many were blocked.
fn check(name: &str, scene: &Soup, segs: &[([f64; 3], [f64; 3])]) -> usize {
    let bvh = Bvh::build(&scene.0, &scene.1, [0.0; 3]);
    let wide = Bvh4::build(&bvh);
    let portable = Bvh4::build(&bvh).portable();
    let mut blocked = 0;
    for (i, &(o, d)) in segs.iter().enumerate() {
        let reference = bvh.any_hit(o, d, |_, _| false).is_some();
        for (path, b4) in [("vector", &wide), ("portable", &portable)] {
            let hit = b4.any_hit_leaf(&bvh, o, d);
            assert_eq!(
                hit.is_some(),
                reference,
                "{name}: segment {i} from {o:?} along {d:?}: the {path} four-wide BVH says blocked = {}, the binary one {reference}",
                hit.is_some()
            );
            if let Some((leaf, k)) = hit {
                assert!(
                    bvh.hits_in_leaf(leaf, k, o, d),
                    "{name}: segment {i}: the {path} blocker (leaf {leaf}, triangle {k}) is not confirmed by hits_in_leaf"
                );
            }
        }
        blocked += reference as usize;
        // The nearest hit: the same distance, or, where a segment crosses
        // the shared edge of two triangles (both hit: the test is widened
        // by EDGE_EPS), the other one a few ulps nearer. The binary
        // traversal keeps the one it met first and skips a leaf entered
        // beyond it; the four-wide one may meet the other first. Both must
        // hit at their stated `t`, the four-wide one never farther, and
        // they may differ by 1e-12 of `t` (Möller–Trumbore's rounding of
        // two triangles through one edge: 1–2 ulps were seen, in 2 of
        // 42,000 segments, both at millimetre scale).
        let near = bvh.closest_hit(o, d);
        for (path, b4) in [("vector", &wide), ("portable", &portable)] {
            let got = b4.closest_hit(&bvh, o, d);
            let hits = |k: u32, t: f64| intersect(&bvh.tris[k as usize], o, d) == Some(t);
            let same = match (near, got) {
                (None, None) => true,
                (Some((ka, ta)), Some((kb, tb))) => {
                    hits(ka, ta) && hits(kb, tb) && tb <= ta && ta - tb <= 1e-12 * ta
                }
                _ => false,
            };
            assert!(
                same,
                "{name}: segment {i}: nearest hit {got:?} through the {path} four-wide BVH, {near:?} through the binary one"
            );
        }
    }
    // Packets: eight consecutive segments (unrelated: each lane's own
    // answer must survive the others' traversal), under masks that leave
    // some lanes out, and eight segments from nearby origins to one end
    // (coherent, as a patch's shadow rays to one light).
    let mut coherent = Vec::new();
    for (i, &(o, d)) in segs.iter().enumerate().step_by(8) {
        let end: [f64; 3] = std::array::from_fn(|k| o[k] + d[k]);
        for (j, &(p, _)) in segs[i..(i + 8).min(segs.len())].iter().enumerate() {
            // Origins within a hundredth of the segment's length of `o`.
            let q: [f64; 3] =
                std::array::from_fn(|k| o[k] + 0.01 * (p[k] - o[k]) * (j as f64 / 8.0));
            coherent.push((q, std::array::from_fn(|k| end[k] - q[k])));
        }
    }
    for (kind, list) in [("unrelated", segs), ("coherent", &coherent[..])] {
        for (g, group) in list.chunks(8).enumerate() {
            let o: [[f64; 3]; 8] = std::array::from_fn(|k| group.get(k).map_or([0.0; 3], |s| s.0));
            let d: [[f64; 3]; 8] = std::array::from_fn(|k| group.get(k).map_or([0.0; 3], |s| s.1));
            let full = ((1u16 << group.len()) - 1) as u8;
            let mask = if g % 3 == 0 { full & 0b1011_0110 } else { full };
            for (path, b4) in [("vector", &wide), ("portable", &portable)] {
                let hits = b4.any_hit_packet(&bvh, &o, &d, mask);
                for k in 0..8 {
                    if mask >> k & 1 == 0 {
                        assert!(
                            hits[k].is_none(),
                            "{name}: a lane outside the mask answered"
                        );
                        continue;
                    }
                    let reference = bvh.any_hit(o[k], d[k], |_, _| false).is_some();
                    assert_eq!(
                        hits[k].is_some(),
                        reference,
                        "{name}: {kind} packet {g}, lane {k} from {:?} along {:?}: the {path} packet says blocked = {}, the binary traversal {reference}",
                        o[k],
                        d[k],
                        hits[k].is_some()
                    );
                    if let Some((leaf, t)) = hits[k] {
                        assert!(bvh.hits_in_leaf(leaf, t, o[k], d[k]));
                    }
                }
                // The nearest hits of the same packet, lane by lane: the
                // same distance, or where a segment crosses the shared edge
                // of two triangles, the other one within 1e-12 of `t`, on
                // either side. A box entered beyond the nearest hit so far
                // is skipped, and a box's entry, rounded, can lie an ulp
                // beyond a triangle on its face; which of the two edge
                // triangles is met first decides, and the packet visits
                // children nearest first where the one-segment traversals
                // visit them in their order (a packet found 1 ulp farther
                // on the millimetre lattice).
                let nearest = b4.closest_hit_packet(&bvh, &o, &d, mask);
                for k in 0..8 {
                    let want = if mask >> k & 1 == 0 {
                        None
                    } else {
                        bvh.closest_hit(o[k], d[k])
                    };
                    let hits =
                        |i: u32, t: f64| intersect(&bvh.tris[i as usize], o[k], d[k]) == Some(t);
                    let same = match (want, nearest[k]) {
                        (None, None) => true,
                        (Some((ka, ta)), Some((kb, tb))) => {
                            hits(ka, ta) && hits(kb, tb) && (ta - tb).abs() <= 1e-12 * ta
                        }
                        _ => false,
                    };
                    assert!(
                        same,
                        "{name}: {kind} packet {g}, lane {k}: nearest hit {:?} through the {path} packet, {want:?} through the binary traversal",
                        nearest[k]
                    );
                }
            }
        }
    }
    // Neither all blocked nor all clear, or the comparison proves little.
    let n = segs.len();
    assert!(
        blocked > n / 20 && blocked < n - n / 20,
        "{name}: {blocked} of {n} segments blocked"
    );
    blocked
}

#[test]
fn four_wide_and_binary_traversals_agree_on_scenes_that_are_not_kind() {
    let mut rng = SplitMix64::new(7);
    for (name, scale, offset) in [
        ("lattice", 1.0, 0.0),
        ("millimetre lattice", 1e-3, 0.0),
        ("kilometre lattice far from the origin", 1e3, 1e5),
    ] {
        let s = lattice(scale, offset);
        let segs = segments(&mut rng, &s, Some((scale, offset)));
        check(name, &s, &segs);
    }
    let s = slivers(&mut rng);
    let segs = segments(&mut rng, &s, None);
    check("slivers", &s, &segs);
    for (name, size, at) in [
        ("soup", 10.0, 0.0),
        ("kilometre soup", 3e3, -2e5),
        ("millimetre soup", 2e-3, 1e-2),
    ] {
        let s = soup(&mut rng, size, at);
        let segs = segments(&mut rng, &s, None);
        check(name, &s, &segs);
    }
}

#[test]
fn the_four_box_test_passes_every_box_the_binary_test_passes() {
    let mut rng = SplitMix64::new(11);
    let mut passed = [0usize; 2];
    for trial in 0..20_000 {
        // Boxes and origins on a coarse lattice half the time, so that
        // origins lie on box planes; directions with zero components.
        let coarse = trial % 2 == 0;
        let val = |rng: &mut SplitMix64| -> f64 {
            let v = rng.uniform() * 8.0 - 4.0;
            if coarse {
                v.round()
            } else {
                v
            }
        };
        let mut n4 = Node4 {
            lo: [[0.0; 4]; 3],
            hi: [[0.0; 4]; 3],
            child: [0; 4],
            valid: 15,
        };
        let mut nodes = [Node::default(); 4];
        for (c, node) in nodes.iter_mut().enumerate() {
            for k in 0..3 {
                let (a, b) = (val(&mut rng) as f32, val(&mut rng) as f32);
                node.min[k] = a.min(b);
                node.max[k] = a.max(b);
                n4.lo[k][c] = node.min[k];
                n4.hi[k][c] = node.max[k];
            }
        }
        let o: [f64; 3] = std::array::from_fn(|_| val(&mut rng));
        let mut d: [f64; 3] = std::array::from_fn(|_| val(&mut rng) * 2.0);
        if trial % 3 == 0 {
            d[(rng.next_u64() % 3) as usize] = 0.0;
        }
        let inv = d.map(|x| 1.0 / x);
        let mut entry = [0.0; 4];
        let portable = test4_portable(&n4, o, inv, &mut entry);
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx") {
            // SAFETY: AVX checked above.
            let mut e = [0.0; 4];
            let vector = unsafe { radiosity::core::bvh4::test4_avx(&n4, o, inv, &mut e) };
            assert_eq!(
                vector, portable,
                "trial {trial}: AVX and portable four-box tests differ"
            );
            assert_eq!(
                e.map(f64::to_bits),
                entry.map(f64::to_bits),
                "trial {trial}: AVX and portable entry parameters differ"
            );
        }
        let nan = (0..3).any(|k| {
            d[k] == 0.0 && (0..4).any(|c| n4.lo[k][c] as f64 == o[k] || n4.hi[k][c] as f64 == o[k])
        });
        for (c, node) in nodes.iter().enumerate() {
            let exact = slab(node, o, inv);
            let binary = exact.is_some();
            let four = portable & (1 << c) != 0;
            // The entry parameter never lies beyond the binary test's (a
            // nearest-hit traversal then skips no box it should visit).
            if let Some(t) = exact {
                assert!(
                    entry[c] <= t,
                    "trial {trial}: box {c} entered at {} after {t}",
                    entry[c]
                );
            }
            assert!(
                !binary || four,
                "trial {trial}: box {c} passes the binary slab test but not the four-box one"
            );
            if !nan {
                assert_eq!(binary, four, "trial {trial}: box {c} without a NaN product");
            }
            passed[binary as usize] += 1;
        }
    }
    assert!(
        passed[0] > 10_000 && passed[1] > 4_000,
        "{passed:?} boxes missed and met"
    );
}

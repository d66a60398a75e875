//! A four-wide view of a [`Bvh`] for the run time's rays: direct light on
//! patches ([`crate::direct`]) casts a shadow ray per sample point
//! and light every frame, and those rays were three quarters of a CPU
//! frame (the interior at 3,499 patches: 9.0 ms of direct light for 0.34 ms
//! of gather; 5.5–5.8 ms through this view); the CPU renderer's primary
//! rays ([`Bvh4::closest_hit`]) were a quarter of the `render` command's
//! samples in `perf`.
//!
//! **Layout.** The binary hierarchy is collapsed top-down: a node's two
//! children are replaced, the largest inner one (by surface area) first, by
//! their own children until four are gathered or only leaves remain (the
//! collapse of Wald et al., "Getting Rid of Packets", 2008). The four boxes
//! are stored by axis (four lows of x, then of y, …), the binary nodes' f32
//! bounds, and widened exactly to f64 when tested, so one vector operation
//! handles an axis of all four children in the binary test's precision; the leaves stay the binary leaves, whose
//! triangles are tested with the same f64 [`intersect`].
//!
//! **Same answer as the binary traversal.** [`Bvh::any_hit`] without a
//! filter finds a hit exactly when some leaf's box passes its slab test and
//! one of its triangles meets the segment (an ancestor's box contains its
//! leaves', so its test passes too: [`Bvh::hits_in_leaf`]). Here the
//! four-wide test computes the same products in the same precision and
//! differs only where a product is NaN (`0 × ∞`, an origin on a box plane
//! with the direction parallel to it): the vector minimum keeps its second
//! operand, and the operands are ordered so that a NaN bound constrains
//! nothing, so a box the binary test passes always passes here; a box may
//! also pass that would not. A triangle hit therefore counts only when its
//! leaf's own box passes the binary test ([`slab`]): [`Bvh4::any_hit_leaf`]
//! answers whether the segment is blocked exactly as the binary traversal
//! does (`tests/bvh4.rs` on generated hostile scenes: slivers, rays along
//! the axes, origins on box planes, kilometre and millimetre scales). The
//! blocking triangle it names may differ (the visiting order differs),
//! which only changes which blocker a [`crate::direct::ShadowCache`]
//! tries first. The nearest hit is the binary traversal's too, but where a
//! segment crosses the shared edge of two triangles (both hit, the test
//! being widened): there the binary traversal keeps the one it met first,
//! this one may meet the other, an ulp or two nearer, first.
//!
//! The box test runs on AVX (four f64 lanes) where the CPU has it, else in
//! the portable [`test4_portable`], which performs the same comparisons.
//!
//! **Packets.** [`Bvh4::any_hit_packet`] traverses up to eight shadow rays
//! together on AVX-512 (a patch's sample points towards one light), one
//! lane a ray through the same operations, with the same answers per ray.
//! Direct light on patches: 0–15 % faster than a ray at a time (the
//! interior at 3,499 patches 5.99 → 5.07 ms in `bench frame`; Sponza's sun
//! no faster: its parallel rays part ways under the arcades). A leaf's
//! triangles are tested against the packet's live lanes at once
//! (`intersect8`: [`intersect`]'s operations lane by lane), where a lane
//! at a time had taken 15 % of the direct pass's samples in `perf`: the
//! direct pass 5.47–5.82 → 4.88–5.23 ms on the interior at 3,499 patches,
//! 2.66–3.04 → 2.07–2.62 ms under Sponza's sun at 3,946 (a scratch
//! program, best of 100, old and new builds alternating, three runs).
//! Each node then asks for the memory of every child a lane enters
//! (`Bvh4::prefetch_children`) before testing any: 5.28–6.47 →
//! 4.99–5.47 ms on the interior, 2.26–3.27 → 2.02–2.44 ms under the sun.
//! A leaf child's triangle range sits in the node's `Slots` line, and its
//! slab test reads the node's own bounds, so a leaf's triangles are asked
//! for with the node and the binary leaf is not read: 4.43–5.30 →
//! 4.36–4.86 ms on the interior (four of six runs faster), 1.87–2.42 →
//! 1.70–2.38 ms under the sun (six of six).

use crate::bvh::{intersect, slab, slab_bounds, Bvh, STACK};

/// Marks a child that is a binary leaf (its low bits are the leaf's index
/// in [`Bvh::nodes`]); others index [`Bvh4::nodes`].
const LEAF: u32 = 1 << 31;

/// Four children: boxes by axis (`lo[axis][child]`), which of the four
/// slots hold a child, and where each points. The bounds are the binary
/// nodes' f32 values, widened to f64 (exactly) when tested: two cache
/// lines a node instead of four.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug)]
pub struct Node4 {
    pub lo: [[f32; 4]; 3],
    pub hi: [[f32; 4]; 3],
    pub child: [u32; 4],
    /// Bit `c` set when slot `c` holds a child.
    pub valid: u32,
}

/// What the packet traversals read of a node beside its f64 bounds, in
/// one cache line: its slots and, for a leaf child, the binary leaf's
/// triangles (first, count), so that a leaf's triangles can be asked for
/// with the node and its slab test read from the node's own bounds (equal
/// to the binary leaf's: [`Bvh4::build`] copies them) instead of from the
/// binary leaf, a dependent load.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default)]
struct Slots {
    child: [u32; 4],
    first: [u32; 4],
    count: [u32; 4],
    valid: u32,
}

/// The four-wide hierarchy (module doc), borrowing nothing: queries take
/// the [`Bvh`] it was built from, whose leaves and triangles it uses.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    pub nodes: Vec<Node4>,
    /// Whether the box test runs on AVX.
    avx: bool,
    /// Whether packets run on AVX-512 ([`Bvh4::any_hit_packet`]).
    avx512: bool,
    /// Where packets run: each node's box bounds converted to f64
    /// (`[lo, hi][axis][child]`, exact), so that the packet test
    /// broadcasts each bound from memory, a load, where from f32 it took
    /// a conversion and a shuffle on the two ports that also do the
    /// test's arithmetic (the interior's direct light 3.23 → 2.95 ms).
    wide: Vec<[[[f64; 4]; 3]; 2]>,
    /// Where packets run: each node's [`Slots`].
    slots: Vec<Slots>,
}

/// Traversal stack of [`Bvh4::any_hit_leaf`]: a node pushes at most three
/// children beyond the one it continues with, and the depth is at most the
/// binary one.
const STACK4: usize = 3 * STACK + 4;

impl Bvh4 {
    /// Collapses `bvh` (module doc).
    pub fn build(bvh: &Bvh) -> Bvh4 {
        let (avx, avx512) = vector_units();
        let mut out = Bvh4 {
            nodes: Vec::new(),
            avx,
            avx512,
            wide: Vec::new(),
            slots: Vec::new(),
        };
        if bvh.tris.is_empty() {
            return out;
        }
        let area = |i: u32| -> f64 {
            let n = &bvh.nodes[i as usize];
            let e: [f64; 3] = std::array::from_fn(|k| n.max[k] as f64 - n.min[k] as f64);
            e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
        };
        // (binary node to collapse, slot of its Node4 once made)
        let mut work = vec![0u32];
        let mut index_of = vec![u32::MAX; bvh.nodes.len()];
        index_of[0] = 0;
        out.nodes.push(empty());
        while let Some(b) = work.pop() {
            let at = index_of[b as usize] as usize;
            let root = &bvh.nodes[b as usize];
            let mut kids: Vec<u32> = if root.count > 0 {
                vec![b]
            } else {
                vec![root.left, root.left + 1]
            };
            while kids.len() < 4 {
                let open = kids
                    .iter()
                    .enumerate()
                    .filter(|(_, &k)| bvh.nodes[k as usize].count == 0)
                    .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
                    .map(|(i, _)| i);
                let Some(i) = open else { break };
                let k = kids.remove(i);
                let l = bvh.nodes[k as usize].left;
                kids.insert(i, l + 1);
                kids.insert(i, l);
            }
            let mut node = empty();
            for (c, &k) in kids.iter().enumerate() {
                let n = &bvh.nodes[k as usize];
                for a in 0..3 {
                    node.lo[a][c] = n.min[a];
                    node.hi[a][c] = n.max[a];
                }
                node.valid |= 1 << c;
                node.child[c] = if n.count > 0 {
                    LEAF | k
                } else {
                    let slot = out.nodes.len() as u32;
                    out.nodes.push(empty());
                    index_of[k as usize] = slot;
                    work.push(k);
                    slot
                };
            }
            out.nodes[at] = node;
        }
        if out.avx512 {
            let f = |b: &[[f32; 4]; 3]| b.map(|a| a.map(f64::from));
            out.wide = out.nodes.iter().map(|n| [f(&n.lo), f(&n.hi)]).collect();
            out.slots = out
                .nodes
                .iter()
                .map(|n| {
                    let mut s = Slots {
                        child: n.child,
                        valid: n.valid,
                        ..Slots::default()
                    };
                    for c in 0..4 {
                        if n.valid >> c & 1 != 0 && n.child[c] & LEAF != 0 {
                            let leaf = &bvh.nodes[(n.child[c] & !LEAF) as usize];
                            (s.first[c], s.count[c]) = (leaf.left, leaf.count);
                        }
                    }
                    s
                })
                .collect();
        }
        out
    }

    /// The same hierarchy with the portable box test, even where the CPU
    /// has AVX (for comparing the two).
    pub fn portable(mut self) -> Bvh4 {
        self.avx = false;
        self.avx512 = false;
        self
    }

    /// Whether the box test runs on AVX.
    pub fn vectorised(&self) -> bool {
        self.avx
    }

    /// Some triangle of `bvh` crossing the segment `o + t d`, `t ∈ [0, 1]`
    /// (its leaf in `bvh` and leaf-order index, for
    /// [`Bvh::hits_in_leaf`]): `Some` exactly when `bvh.any_hit` without a
    /// filter is (module doc).
    pub fn any_hit_leaf(&self, bvh: &Bvh, o: [f64; 3], d: [f64; 3]) -> Option<(u32, u32)> {
        if self.nodes.is_empty() {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only where the CPU reports AVX.
            return unsafe { self.any_hit_avx(bvh, o, d) };
        }
        self.traverse(bvh, o, d, test4_portable)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn any_hit_avx(&self, bvh: &Bvh, o: [f64; 3], d: [f64; 3]) -> Option<(u32, u32)> {
        self.traverse(bvh, o, d, |n, o, inv, e| unsafe { test4_avx(n, o, inv, e) })
    }

    /// The traversal, with the four-box test `test` (inlined into each
    /// caller, so the AVX build compiles it for AVX).
    #[inline(always)]
    fn traverse(
        &self,
        bvh: &Bvh,
        o: [f64; 3],
        d: [f64; 3],
        test: impl Fn(&Node4, [f64; 3], [f64; 3], &mut [f64; 4]) -> u32,
    ) -> Option<(u32, u32)> {
        let inv = d.map(|x| 1.0 / x);
        let mut stack = [0u32; STACK4];
        let mut sp = 0usize;
        let mut node = 0u32;
        loop {
            let n = &self.nodes[node as usize];
            let mut entry = [0.0f64; 4];
            let mut bits = test(n, o, inv, &mut entry) & n.valid;
            let mut next = None;
            while bits != 0 {
                let c = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let child = n.child[c];
                if child & LEAF != 0 {
                    let leaf = child & !LEAF;
                    let ln = &bvh.nodes[leaf as usize];
                    for k in ln.left..ln.left + ln.count {
                        if intersect(&bvh.tris[k as usize], o, d).is_some()
                            && slab(ln, o, inv).is_some()
                        {
                            return Some((leaf, k));
                        }
                    }
                } else if next.is_none() {
                    next = Some(child);
                } else {
                    assert!(sp < STACK4, "BVH4 traversal stack overflow");
                    stack[sp] = child;
                    sp += 1;
                }
            }
            node = match next {
                Some(c) => c,
                None if sp > 0 => {
                    sp -= 1;
                    stack[sp]
                }
                None => return None,
            };
        }
    }
}

impl Bvh4 {
    /// The nearest triangle of `bvh` crossing the segment `o + t d`, `t ∈
    /// (0, 1]`: its leaf-order index and `t`, as [`Bvh::closest_hit`]
    /// finds it (module doc: the same candidates, each leaf's own box
    /// passing the binary slab test; where two triangles lie at exactly
    /// the same `t`, the one met first, which the visiting order decides).
    /// Children are visited nearer first, and a box entered beyond the
    /// nearest hit so far is skipped.
    pub fn closest_hit(&self, bvh: &Bvh, o: [f64; 3], d: [f64; 3]) -> Option<(u32, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only where the CPU reports AVX.
            return unsafe { self.closest_avx(bvh, o, d) };
        }
        self.closest(bvh, o, d, test4_portable)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn closest_avx(&self, bvh: &Bvh, o: [f64; 3], d: [f64; 3]) -> Option<(u32, f64)> {
        self.closest(bvh, o, d, |n, o, inv, e| unsafe { test4_avx(n, o, inv, e) })
    }

    #[inline(always)]
    fn closest(
        &self,
        bvh: &Bvh,
        o: [f64; 3],
        d: [f64; 3],
        test: impl Fn(&Node4, [f64; 3], [f64; 3], &mut [f64; 4]) -> u32,
    ) -> Option<(u32, f64)> {
        let inv = d.map(|x| 1.0 / x);
        let mut best: Option<(u32, f64)> = None;
        let mut stack = [(0u32, 0.0f64); STACK4];
        stack[0] = (0, 0.0);
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let (node, entry) = stack[sp];
            if best.is_some_and(|(_, bt)| entry > bt) {
                continue;
            }
            let n = &self.nodes[node as usize];
            let mut t0 = [0.0f64; 4];
            let mut bits = test(n, o, inv, &mut t0) & n.valid;
            let mut inner = [(0.0f64, 0u32); 4];
            let mut m = 0;
            while bits != 0 {
                let c = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if best.is_some_and(|(_, bt)| t0[c] > bt) {
                    continue;
                }
                let child = n.child[c];
                if child & LEAF == 0 {
                    inner[m] = (t0[c], child);
                    m += 1;
                    continue;
                }
                let ln = &bvh.nodes[(child & !LEAF) as usize];
                if slab(ln, o, inv).is_some() {
                    bvh.nearest_in_leaf(ln, o, d, &mut best);
                }
            }
            // The farther pushed first, so the nearer is popped first.
            inner[..m].sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
            for &(t, c) in &inner[..m] {
                assert!(sp < STACK4, "BVH4 traversal stack overflow");
                stack[sp] = (c, t);
                sp += 1;
            }
        }
        best
    }
}

/// Rays in one [`Bvh4::any_hit_packet`] query.
pub const PACKET: usize = 8;

impl Bvh4 {
    /// [`Bvh4::any_hit_leaf`] of up to [`PACKET`] segments `o[k] + t d[k]`,
    /// `t ∈ [0, 1]`, for the `k` set in `mask`, traversed together: on
    /// AVX-512 each child box is tested against the eight segments at once
    /// (one lane a segment, the same operations as the four-box test, so a
    /// box passes for a segment exactly when it does there), a node is
    /// visited while some unblocked segment passes it, and a leaf's
    /// triangles are tested for each such segment as in
    /// [`Bvh4::any_hit_leaf`] (the hit counting only where the leaf's own box
    /// passes the binary test). So each segment is blocked exactly when
    /// [`Bvh4::any_hit_leaf`] says it is; the blocker named may differ.
    /// Shadow rays from a patch's sample points to one light share most of
    /// their nodes. Elsewhere (no AVX-512, or [`Bvh4::portable`]): one
    /// [`Bvh4::any_hit_leaf`] per segment.
    pub fn any_hit_packet(
        &self,
        bvh: &Bvh,
        o: &[[f64; 3]; PACKET],
        d: &[[f64; 3]; PACKET],
        mask: u8,
    ) -> [Option<(u32, u32)>; PACKET] {
        let mut out = [None; PACKET];
        if self.nodes.is_empty() || mask == 0 {
            return out;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            // SAFETY: `avx512` is set only where the CPU reports AVX-512F.
            unsafe { self.packet_avx512(bvh, o, d, mask, &mut out) };
            return out;
        }
        for k in 0..PACKET {
            if mask >> k & 1 != 0 {
                out[k] = self.any_hit_leaf(bvh, o[k], d[k]);
            }
        }
        out
    }

    /// [`Bvh4::closest_hit`] of up to [`PACKET`] segments `o[k] + t d[k]`
    /// for the `k` set in `mask`, traversed together on AVX-512: each child
    /// box is tested against the eight segments at once (the four-box
    /// test's operations lane by lane), a lane skips a box it enters beyond
    /// its nearest hit so far, children are visited nearest first for the
    /// packet's first live segment, and a leaf's triangles are tested per
    /// segment as [`Bvh4::closest_hit`] tests them. So each lane's distance
    /// is the one [`Bvh4::closest_hit`] finds; where two triangles lie at
    /// exactly the same distance the one named may differ (the visiting
    /// order decides, as between the binary and four-wide traversals).
    /// Camera rays through neighbouring pixels share most of their nodes.
    /// Elsewhere: one [`Bvh4::closest_hit`] per segment.
    pub fn closest_hit_packet(
        &self,
        bvh: &Bvh,
        o: &[[f64; 3]; PACKET],
        d: &[[f64; 3]; PACKET],
        mask: u8,
    ) -> [Option<(u32, f64)>; PACKET] {
        let mut out = [None; PACKET];
        if self.nodes.is_empty() || mask == 0 {
            return out;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            // SAFETY: `avx512` is set only where the CPU reports AVX-512F.
            unsafe { self.closest_packet_avx512(bvh, o, d, mask, &mut out) };
            return out;
        }
        for k in 0..PACKET {
            if mask >> k & 1 != 0 {
                out[k] = self.closest_hit(bvh, o[k], d[k]);
            }
        }
        out
    }

    /// [`Bvh4::closest_hit_packet`] on AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn closest_packet_avx512(
        &self,
        bvh: &Bvh,
        o: &[[f64; 3]; PACKET],
        d: &[[f64; 3]; PACKET],
        mask: u8,
        out: &mut [Option<(u32, f64)>; PACKET],
    ) {
        use std::arch::x86_64::*;
        let (inv, ov, iv) = packet_lanes(o, d);
        // Per lane the nearest hit's distance so far (∞ for none).
        let mut best = [f64::INFINITY; PACKET];
        let mut stack = [(0u32, 0u8); STACK4];
        stack[0] = (0, mask);
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let (node, rays) = stack[sp];
            let n = &self.slots[node as usize];
            let (t0s, passes) = boxes8(&self.wide[node as usize], &ov, &iv);
            self.prefetch_children::<true>(bvh, node, &passes, rays);
            // Children by the entry of the first live lane, nearest first.
            let lead = (rays.trailing_zeros() as usize).min(PACKET - 1);
            let mut entry = [0.0f64; 4];
            for c in 0..4 {
                let mut v = [0.0f64; PACKET];
                _mm512_storeu_pd(v.as_mut_ptr(), t0s[c]);
                entry[c] = v[lead];
            }
            let mut order = [0usize, 1, 2, 3];
            order.sort_unstable_by(|&a, &b| entry[a].total_cmp(&entry[b]));
            let mut inner = [(0u32, 0u8); 4];
            let mut m = 0;
            for &c in &order {
                if n.valid >> c & 1 == 0 {
                    continue;
                }
                // Lanes that cross the box no farther than their nearest
                // hit so far (which the leaves before may have moved).
                let near = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(t0s[c], _mm512_loadu_pd(best.as_ptr()));
                let pass = passes[c] & rays & near;
                if pass == 0 {
                    continue;
                }
                let child = n.child[c];
                if child & LEAF == 0 {
                    inner[m] = (child, pass);
                    m += 1;
                    continue;
                }
                let ln = &bvh.nodes[(child & !LEAF) as usize];
                let mut left = pass;
                while left != 0 {
                    let k = left.trailing_zeros() as usize;
                    left &= left - 1;
                    if slab(ln, o[k], inv[k]).is_some() {
                        bvh.nearest_in_leaf(ln, o[k], d[k], &mut out[k]);
                        if let Some((_, t)) = out[k] {
                            best[k] = t;
                        }
                    }
                }
            }
            // The farther pushed first, so the nearer is popped first.
            for &x in inner[..m].iter().rev() {
                assert!(sp < STACK4, "BVH4 packet traversal stack overflow");
                stack[sp] = x;
                sp += 1;
            }
        }
    }

    /// Asks for the memory of `n`'s children that some lane of `rays`
    /// enters (`passes` per child): an inner child's f64 bounds and its
    /// [`Slots`], a leaf's triangles (and binary node with `LEAF_NODES`). A hint, no effect
    /// on results:
    /// the traversal's time went to waiting for these lines (`perf`:
    /// half the samples of the packet traversal at the loads of a node's
    /// bounds, slots, leaf node and triangles), and asking for every
    /// entered child at once lets those misses overlap while the node's
    /// leaves are tested.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn prefetch_children<const LEAF_NODES: bool>(
        &self,
        bvh: &Bvh,
        node: u32,
        passes: &[u8; 4],
        rays: u8,
    ) {
        use std::arch::x86_64::*;
        let n = &self.slots[node as usize];
        let mut v = n.valid;
        while v != 0 {
            let c = v.trailing_zeros() as usize;
            v &= v - 1;
            if passes[c] & rays == 0 {
                continue;
            }
            let child = n.child[c];
            if child & LEAF != 0 {
                // Its triangles, and the binary leaf where it is read
                // (`LEAF_NODES`: the nearest-hit traversal; the any-hit one
                // reads the leaf's range and bounds from this node).
                if LEAF_NODES {
                    let p = bvh.nodes.as_ptr().wrapping_add((child & !LEAF) as usize);
                    _mm_prefetch::<_MM_HINT_T0>(p.cast());
                }
                let t = bvh.tris.as_ptr().wrapping_add(n.first[c] as usize) as *const i8;
                let bytes = n.count[c] as usize * std::mem::size_of::<crate::bvh::Tri>();
                for off in (0..bytes).step_by(64) {
                    _mm_prefetch::<_MM_HINT_T0>(t.wrapping_add(off));
                }
            } else {
                // Three lines of bounds (192 bytes) and the slots' line.
                let w = self.wide.as_ptr().wrapping_add(child as usize) as *const i8;
                _mm_prefetch::<_MM_HINT_T0>(w);
                _mm_prefetch::<_MM_HINT_T0>(w.wrapping_add(64));
                _mm_prefetch::<_MM_HINT_T0>(w.wrapping_add(128));
                let q = self.slots.as_ptr().wrapping_add(child as usize);
                _mm_prefetch::<_MM_HINT_T0>(q.cast());
            }
        }
    }

    /// [`Bvh4::any_hit_packet`] on AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn packet_avx512(
        &self,
        bvh: &Bvh,
        o: &[[f64; 3]; PACKET],
        d: &[[f64; 3]; PACKET],
        mask: u8,
        out: &mut [Option<(u32, u32)>; PACKET],
    ) {
        let (inv, ov, iv) = packet_lanes(o, d);
        let dv = by_axis(d);
        let mut active = mask;
        let mut stack = [(0u32, 0u8); STACK4];
        let mut sp = 0usize;
        let (mut node, mut rays) = (0u32, mask);
        loop {
            let n = &self.slots[node as usize];
            let w = &self.wide[node as usize];
            let (_, passes) = boxes8(w, &ov, &iv);
            self.prefetch_children::<false>(bvh, node, &passes, rays & active);
            let mut next = None;
            let mut valid = n.valid;
            while valid != 0 {
                let c = valid.trailing_zeros() as usize;
                valid &= valid - 1;
                let pass = passes[c] & rays & active;
                if pass == 0 {
                    continue;
                }
                let child = n.child[c];
                if child & LEAF != 0 {
                    let leaf = child & !LEAF;
                    // A hit counts only where the leaf's own box passes
                    // the binary test (module doc; its bounds are this
                    // node's for the child, `slab_of`): those lanes, then
                    // the leaf's triangles in order against all of them at
                    // once, each lane taking its first hit, as a lane at
                    // a time took it.
                    let mut left = 0u8;
                    let mut bits = pass;
                    while bits != 0 {
                        let k = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        if slab_of(w, c, o[k], inv[k]) {
                            left |= 1 << k;
                        }
                    }
                    for t in n.first[c]..n.first[c] + n.count[c] {
                        if left == 0 {
                            break;
                        }
                        let mut hit = intersect8(&bvh.tris[t as usize], &ov, &dv, left);
                        left &= !hit;
                        active &= !hit;
                        while hit != 0 {
                            let k = hit.trailing_zeros() as usize;
                            hit &= hit - 1;
                            out[k] = Some((leaf, t));
                        }
                    }
                    if active == 0 {
                        return;
                    }
                } else if next.is_none() {
                    next = Some((child, pass));
                } else {
                    assert!(sp < STACK4, "BVH4 packet traversal stack overflow");
                    stack[sp] = (child, pass);
                    sp += 1;
                }
            }
            // The next node some unblocked segment still passes.
            loop {
                let (c, r) = match next.take() {
                    Some(x) => x,
                    None if sp > 0 => {
                        sp -= 1;
                        stack[sp]
                    }
                    None => return,
                };
                if r & active != 0 {
                    (node, rays) = (c, r & active);
                    break;
                }
            }
        }
    }
}

/// [`slab`] of child `c`'s box from a node's f64 bounds (`[lo, hi][axis]
/// [child]`, the binary node's f32 bounds widened exactly): the same
/// operations on the same values, so the same answer.
#[inline]
fn slab_of(w: &[[[f64; 4]; 3]; 2], c: usize, o: [f64; 3], inv: [f64; 3]) -> bool {
    let [lo, hi] = w.map(|b| b.map(|axis| axis[c]));
    slab_bounds(lo, hi, o, inv).is_some()
}

/// The lanes of `lanes` whose segment (origin `ov`, direction `dv`, one
/// lane a segment) meets `tri`: [`intersect`]'s operations lane by lane,
/// in its order and precision, so a lane hits exactly when [`intersect`]
/// does for its segment (a NaN fails the same comparisons: ordered ones,
/// and `det == 0` as the only rejection a NaN passes).
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn intersect8(
    tri: &crate::bvh::Tri,
    ov: &[std::arch::x86_64::__m512d; 3],
    dv: &[std::arch::x86_64::__m512d; 3],
    lanes: u8,
) -> u8 {
    use crate::bvh::EDGE_EPS;
    use crate::math::{f64s, sub};
    use std::arch::x86_64::*;
    let v0 = f64s(tri.v0);
    let e1 = sub(f64s(tri.v1), v0).map(|x| _mm512_set1_pd(x));
    let e2 = sub(f64s(tri.v2), v0).map(|x| _mm512_set1_pd(x));
    let (mul, subv, add) = (_mm512_mul_pd, _mm512_sub_pd, _mm512_add_pd);
    // cross(a, b) and dot(a, b) of core::math, lane by lane.
    let cross = |a: &[__m512d; 3], b: &[__m512d; 3]| {
        [
            subv(mul(a[1], b[2]), mul(a[2], b[1])),
            subv(mul(a[2], b[0]), mul(a[0], b[2])),
            subv(mul(a[0], b[1]), mul(a[1], b[0])),
        ]
    };
    let dot = |a: &[__m512d; 3], b: &[__m512d; 3]| {
        add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
    };
    let p = cross(dv, &e2);
    let det = dot(&e1, &p);
    let mut m = lanes & _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(det, _mm512_setzero_pd());
    if m == 0 {
        return 0;
    }
    let inv = _mm512_div_pd(_mm512_set1_pd(1.0), det);
    let s: [__m512d; 3] = std::array::from_fn(|a| subv(ov[a], _mm512_set1_pd(v0[a])));
    let u = mul(dot(&s, &p), inv);
    let (lo, hi) = (_mm512_set1_pd(-EDGE_EPS), _mm512_set1_pd(1.0 + EDGE_EPS));
    m &= _mm512_cmp_pd_mask::<_CMP_LE_OQ>(lo, u) & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(u, hi);
    if m == 0 {
        return 0;
    }
    let q = cross(&s, &e1);
    let v = mul(dot(dv, &q), inv);
    m &= !(_mm512_cmp_pd_mask::<_CMP_LT_OQ>(v, lo)
        | _mm512_cmp_pd_mask::<_CMP_GT_OQ>(add(u, v), hi));
    let t = mul(dot(&e2, &q), inv);
    let (zero, one) = (_mm512_setzero_pd(), _mm512_set1_pd(1.0));
    m & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(zero, t) & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(t, one)
}

/// A packet's inverse directions, and its origins and inverse directions
/// by coordinate, one lane a segment: what [`boxes8`] takes.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
#[allow(clippy::type_complexity)]
unsafe fn packet_lanes(
    o: &[[f64; 3]; PACKET],
    d: &[[f64; 3]; PACKET],
) -> (
    [[f64; 3]; PACKET],
    [std::arch::x86_64::__m512d; 3],
    [std::arch::x86_64::__m512d; 3],
) {
    let inv: [[f64; 3]; PACKET] = std::array::from_fn(|k| d[k].map(|x| 1.0 / x));
    (inv, by_axis(o), by_axis(&inv))
}

/// Eight 3-vectors by coordinate, one lane a vector.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn by_axis(v: &[[f64; 3]; PACKET]) -> [std::arch::x86_64::__m512d; 3] {
    std::array::from_fn(|a| {
        let lane: [f64; PACKET] = std::array::from_fn(|k| v[k][a]);
        // SAFETY: eight f64, unaligned load; AVX-512F as the caller's.
        unsafe { std::arch::x86_64::_mm512_loadu_pd(lane.as_ptr()) }
    })
}

/// A node's four child boxes against eight segments (lane by lane: origin
/// `ov`, inverse direction `iv`), from its bounds in f64 (`[lo, hi][axis]
/// [child]`): per child the entry parameters and the lanes whose segment
/// meets the box within `t ∈ [0, 1]`. The operations of [`test4_avx`]
/// lane by lane, so a box passes for a segment exactly when it does
/// there. The four tests run first, without branches, so that their
/// dependency chains overlap (a child at a time, each test waited for
/// before the next: the interior's direct light at 3,499 patches
/// 4.58–4.64 ms, against 4.43–4.48 so and 4.93–4.98 a ray at a time).
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn boxes8(
    wide: &[[[f64; 4]; 3]; 2],
    ov: &[std::arch::x86_64::__m512d; 3],
    iv: &[std::arch::x86_64::__m512d; 3],
) -> ([std::arch::x86_64::__m512d; 4], [u8; 4]) {
    use std::arch::x86_64::*;
    let [wlo, whi] = wide;
    let (zero, one) = (_mm512_setzero_pd(), _mm512_set1_pd(1.0));
    let mut t0s = [zero; 4];
    let mut passes = [0u8; 4];
    for c in 0..4 {
        let (mut t0, mut t1) = (zero, one);
        for a in 0..3 {
            let lo = _mm512_set1_pd(wlo[a][c]);
            let hi = _mm512_set1_pd(whi[a][c]);
            let x = _mm512_mul_pd(_mm512_sub_pd(lo, ov[a]), iv[a]);
            let y = _mm512_mul_pd(_mm512_sub_pd(hi, ov[a]), iv[a]);
            // As test4_avx: min(x, y), max(x, y), then the NaN operand
            // first against t0, t1.
            t0 = _mm512_max_pd(_mm512_min_pd(x, y), t0);
            t1 = _mm512_min_pd(_mm512_max_pd(x, y), t1);
        }
        t0s[c] = t0;
        passes[c] = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(t0, t1);
    }
    (t0s, passes)
}

fn empty() -> Node4 {
    Node4 {
        lo: [[0.0; 4]; 3],
        hi: [[0.0; 4]; 3],
        child: [0; 4],
        valid: 0,
    }
}

/// Whether this CPU runs the AVX box test, and packets on AVX-512.
fn vector_units() -> (bool, bool) {
    #[cfg(target_arch = "x86_64")]
    {
        (
            is_x86_feature_detected!("avx"),
            is_x86_feature_detected!("avx512f"),
        )
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        (false, false)
    }
}

/// The four slab tests of `n` against the segment from `o` with inverse
/// direction `inv`: bit `c` set when child `c`'s box meets `t ∈ [0, 1]`,
/// and `entry[c]` the segment's entry parameter into it.
/// Per axis `a = (lo − o) inv`, `b = (hi − o) inv`, then, as the vector
/// instructions do, `min(a, b) = a < b ? a : b`, `max(a, b) = a > b ? a :
/// b`, `t0 = lo > t0 ? lo : t0`, `t1 = hi < t1 ? hi : t1` (module doc: a
/// NaN bound leaves `t0`, `t1` as they are).
pub fn test4_portable(n: &Node4, o: [f64; 3], inv: [f64; 3], entry: &mut [f64; 4]) -> u32 {
    let mut bits = 0;
    for (c, e) in entry.iter_mut().enumerate() {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for k in 0..3 {
            let a = (n.lo[k][c] as f64 - o[k]) * inv[k];
            let b = (n.hi[k][c] as f64 - o[k]) * inv[k];
            let lo = if a < b { a } else { b };
            let hi = if a > b { a } else { b };
            t0 = if lo > t0 { lo } else { t0 };
            t1 = if hi < t1 { hi } else { t1 };
        }
        *e = t0;
        if t0 <= t1 {
            bits |= 1 << c;
        }
    }
    bits
}

/// [`test4_portable`] on AVX: the same operations, four boxes at once
/// (`vminpd`/`vmaxpd` return their second operand when either is NaN).
///
/// # Safety
/// The CPU must support AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
pub unsafe fn test4_avx(n: &Node4, o: [f64; 3], inv: [f64; 3], entry: &mut [f64; 4]) -> u32 {
    use std::arch::x86_64::*;
    let mut t0 = _mm256_setzero_pd();
    let mut t1 = _mm256_set1_pd(1.0);
    for k in 0..3 {
        let (ok, ik) = (_mm256_set1_pd(o[k]), _mm256_set1_pd(inv[k]));
        let lo = _mm256_cvtps_pd(_mm_loadu_ps(n.lo[k].as_ptr()));
        let hi = _mm256_cvtps_pd(_mm_loadu_ps(n.hi[k].as_ptr()));
        let a = _mm256_mul_pd(_mm256_sub_pd(lo, ok), ik);
        let b = _mm256_mul_pd(_mm256_sub_pd(hi, ok), ik);
        // min(a, b): a where a < b, else b (so b where either is NaN).
        let lo = _mm256_min_pd(a, b);
        let hi = _mm256_max_pd(a, b);
        // max(lo, t0): t0 where lo is NaN.
        t0 = _mm256_max_pd(lo, t0);
        t1 = _mm256_min_pd(hi, t1);
    }
    _mm256_storeu_pd(entry.as_mut_ptr(), t0);
    _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LE_OQ>(t0, t1)) as u32
}

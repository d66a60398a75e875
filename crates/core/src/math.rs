//! Small f64 vector helpers on `[f64; 3]`, the representation the bake's
//! CPU references use (they mirror kernels that work on plain arrays), and
//! the seeded generator behind every reproducible random input.

/// `a − b`.
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a · b`.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a / |a|` (NaN for the zero vector; callers pass non-zero vectors).
pub fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    a.map(|x| x / l)
}

/// SplitMix64 (Steele, Lea & Flood, "Fast splittable pseudorandom number
/// generators", OOPSLA 2014): tiny and seeded, so random lights and test
/// matrices are the same on every machine.
#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Point `k` of the (0, 2)-sequence in base 2 (Sobol', 1967: the van der
/// Corput sequence and Sobol's second dimension, whose direction numbers
/// follow `v ← v ⊕ (v >> 1)`; Kollig & Keller, "Efficient Multidimensional
/// Sampling", Eurographics 2002), digitally shifted by `shift` (each 32-bit
/// fraction XORed with it). Every prefix of `2^m` points is a (0, m, 2)-net:
/// one point in each dyadic box of area `2^-m`, so in particular its
/// projection on either axis has one point in each interval
/// `[j 2^-m, (j + 1) 2^-m)`. The digital shift maps dyadic intervals onto
/// dyadic intervals, so shifted points keep that property.
pub fn sobol02(k: u32, shift: [u32; 2]) -> [f64; 2] {
    let a = k.reverse_bits();
    let (mut b, mut v, mut i) = (0u32, 1u32 << 31, k);
    while i != 0 {
        if i & 1 != 0 {
            b ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    let f = |x: u32| x as f64 * (1.0 / 4_294_967_296.0);
    [f(a ^ shift[0]), f(b ^ shift[1])]
}

/// `a + b`.
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `s a`.
pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// `|a|`.
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `a / |a|`, computed as a multiplication by `1 / |a|` (the form-factor
/// kernel's rounding; [`normalize`] divides).
pub fn unit(a: [f64; 3]) -> [f64; 3] {
    scale(a, 1.0 / dot(a, a).sqrt())
}

/// An `[f32; 3]` widened to f64.
pub fn f64s(v: [f32; 3]) -> [f64; 3] {
    v.map(f64::from)
}

/// An orthonormal tangent basis `(t, b)` of the unit vector `n`, with
/// `t × b = n`, continuous except at `n_z = −1`'s sign flip: Duff et al.,
/// "Building an Orthonormal Basis, Revisited", JCGT 6(1), 2017.
pub fn tangent_basis(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let sign = 1f64.copysign(n[2]);
    let a = -1.0 / (sign + n[2]);
    let b = n[0] * n[1] * a;
    (
        [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]],
        [b, sign + n[1] * n[1] * a, -n[1]],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The property the patches' sample points rely on: for any digital
    /// shift, the first 8 and the first 16 points have one point in each
    /// eighth (sixteenth) of [0, 1) along either axis, and the first 16
    /// one point in each dyadic box of area 1/16 (4 × 4, 2 × 8, 8 × 2).
    #[test]
    fn sobol02_prefixes_are_nets_for_any_shift() {
        let mut rng = SplitMix64::new(7);
        for trial in 0..200 {
            let r = rng.next_u64();
            let shift = if trial == 0 {
                [0, 0]
            } else {
                [r as u32, (r >> 32) as u32]
            };
            let pts: Vec<[f64; 2]> = (0..16).map(|k| sobol02(k, shift)).collect();
            assert!(pts.iter().flatten().all(|&x| (0.0..1.0).contains(&x)));
            for (m, count) in [(3u32, 8usize), (4, 16)] {
                for a in 0..=m {
                    let (cx, cy) = (1usize << a, 1usize << (m - a));
                    let mut seen = vec![false; cx * cy];
                    for p in &pts[..count] {
                        let cell = (p[0] * cx as f64) as usize * cy + (p[1] * cy as f64) as usize;
                        assert!(!seen[cell], "two of the first {count} points share a {cx} × {cy} box (shift {shift:?})");
                        seen[cell] = true;
                    }
                }
            }
        }
    }
}

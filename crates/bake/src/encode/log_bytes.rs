//! The log bytes of the dense part (the codec module doc, step 2): a value
//! `v` of a channel with maximum `m` and log range `l` becomes
//! `round(255/l · (ln(v/m) + l))`, clamped to [0, 255]. [`log_byte`] is the
//! definition, in f64; [`LogBytes`] gives the same byte for every f32 from
//! 255 thresholds found once per channel, so that the encoder's inner loop
//! looks up and compares instead of taking a logarithm.

/// The log byte of a dense value `v ≥ 0` for maximum `m` and range `l`
/// (the definition [`LogBytes`] reproduces).
pub fn log_byte(v: f32, m: f32, l: f32) -> u8 {
    if !(v > 0.0) || !(m > 0.0) {
        return 0;
    }
    let x = 255.0 / l as f64 * ((v as f64 / m as f64).ln() + l as f64);
    x.round().clamp(0.0, 255.0) as u8
}

/// [`log_byte`] for one `(m, l)` from thresholds: `thresholds[b − 1]` is
/// the smallest f32 whose byte is at least `b` (NaN where no value reaches
/// it, which no comparison passes), so the byte of `v > 0` is the number
/// of thresholds at or below `v`. A table on the top 16 bits of `v`'s
/// pattern (exponent and 8 mantissa bits, a bucket 1/256 of an octave
/// wide, under one byte level for any range ≥ 1, the automatic range's
/// least) gives the byte of the bucket's lowest value; a comparison or
/// two finish it (more for a range set below 1, still exact).
///
/// This equals [`log_byte`] for every f32 because the byte never decreases
/// as `v` grows: `v/m` is a correctly rounded division, `ln` is monotonic
/// to within its rounding, and `round` and `clamp` keep order; the
/// thresholds are found by bisection over the f32 bit patterns (which
/// positive floats order as their values) with [`log_byte`] itself. The
/// unit tests check it on every f32 within 64 ulps of each threshold and on
/// random values.
#[derive(Clone, Debug)]
pub struct LogBytes {
    thresholds: [f32; 255],
    /// The byte of `f32::from_bits(k << 15)`, for each 16-bit `k`.
    bucket: Vec<u8>,
}

/// The bits below a [`LogBytes`] bucket's index.
const BUCKET_SHIFT: u32 = 15;

impl LogBytes {
    /// The thresholds and table of maximum `m` and range `l`.
    pub fn new(m: f32, l: f32) -> LogBytes {
        // The positive f32 bit patterns, 1 (the smallest subnormal) to
        // +∞, where the byte is 255 for any m > 0 and range > 0 (the
        // codec's settings refuse a negative range).
        const INF: u32 = 0x7f80_0000;
        let mut thresholds = [f32::NAN; 255];
        if m > 0.0 {
            let byte = |bits: u32| log_byte(f32::from_bits(bits), m, l);
            for (t, b) in thresholds.iter_mut().zip(1u8..=255) {
                // The smallest pattern in (lo, hi] with byte ≥ b.
                let (mut lo, mut hi) = (0u32, INF);
                if byte(hi) < b {
                    break;
                }
                while hi - lo > 1 {
                    let mid = lo + (hi - lo) / 2;
                    if byte(mid) >= b {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                *t = f32::from_bits(hi);
            }
        }
        // Bucket starts rise with k (up to +∞; the NaN patterns past it
        // compare false and keep the last byte, and are never looked up).
        let mut bucket = vec![0u8; 1 << (32 - BUCKET_SHIFT)];
        let mut b = 0usize;
        for (k, out) in bucket.iter_mut().enumerate() {
            let v0 = f32::from_bits((k as u32) << BUCKET_SHIFT);
            while b < 255 && thresholds[b] <= v0 {
                b += 1;
            }
            *out = b as u8;
        }
        LogBytes { thresholds, bucket }
    }

    /// The byte of `v` ([`log_byte`] of this `(m, l)`): 0 for `v ≤ 0` and
    /// NaN, else how many thresholds are at or below `v`.
    #[inline]
    pub fn byte(&self, v: f32) -> u8 {
        if !(v > 0.0) {
            return 0;
        }
        let mut b = self.bucket[(v.to_bits() >> BUCKET_SHIFT) as usize] as usize;
        while b < 255 && self.thresholds[b] <= v {
            b += 1;
        }
        b as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Maxima and ranges like the encoder's (the automatic range is
    /// clamped to [1, 30]; the thesis's is 25; a set one may be any
    /// positive value), maxima from tiny to huge.
    fn settings() -> Vec<(f32, f32)> {
        let mut v = Vec::new();
        for &m in &[1e-30f32, 3.7e-9, 0.0123, 1.0, 0.9999999, 7.5e4, 3.0e30] {
            for &l in &[0.05f32, 1.0, 2.5, 5.3, 12.0, 25.0, 30.0, 200.0] {
                v.push((m, l));
            }
        }
        v
    }

    #[test]
    fn the_thresholds_give_log_byte_on_every_float_near_each_threshold() {
        for (m, l) in settings() {
            let lb = LogBytes::new(m, l);
            for &t in &lb.thresholds {
                if !t.is_finite() {
                    continue;
                }
                let bits = t.to_bits();
                for b in bits.saturating_sub(64)..=bits.saturating_add(64).min(0x7f80_0000) {
                    let v = f32::from_bits(b);
                    assert_eq!(
                        lb.byte(v),
                        log_byte(v, m, l),
                        "v = {v:e}, m = {m:e}, l = {l}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_thresholds_give_log_byte_on_random_and_special_values() {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for (m, l) in settings() {
            let lb = LogBytes::new(m, l);
            for v in [
                0.0f32,
                -0.0,
                -1.0,
                f32::NAN,
                f32::INFINITY,
                f32::MAX,
                m,
                m * 2.0,
            ] {
                assert_eq!(
                    lb.byte(v),
                    log_byte(v, m, l),
                    "v = {v:e}, m = {m:e}, l = {l}"
                );
            }
            for _ in 0..20_000 {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                // Any positive finite pattern, and values within e^-l·m…m,
                // where the bytes change.
                let any = f32::from_bits((s as u32) % 0x7f80_0000);
                let near = m * (-(l as f64) * ((s >> 32) as f64 / u32::MAX as f64)).exp() as f32;
                for v in [any, near] {
                    assert_eq!(
                        lb.byte(v),
                        log_byte(v, m, l),
                        "v = {v:e}, m = {m:e}, l = {l}"
                    );
                }
            }
        }
    }

    #[test]
    fn no_maximum_gives_every_value_byte_zero() {
        for m in [0.0f32, -1.0, f32::NAN] {
            let lb = LogBytes::new(m, 25.0);
            assert_eq!(lb.byte(1.0), 0);
            assert_eq!(lb.byte(f32::INFINITY), 0);
        }
    }
}

//! What every encoding of one matrix shares, made once for all of the codec
//! choice's candidates ([`Prepared`]): the distinct channels, their maxima
//! and total mass, and the sparse part's ranking. Each candidate keeps the
//! top `count` entries by the key `Σ_c t_c / max_c` (f32, in channel order,
//! as its bit pattern; ties in row-major order) as its
//! exact sparse part; the threshold of every count comes from two
//! histograms of the keys' bit patterns, a radix select (high 16 bits once
//! per matrix, then the low 16 bits of the buckets the counts fall in, all
//! counts in one pass: [`Prepared::prepare`]). A candidate then finds its
//! positions and the dense part's maxima in one pass over the matrix
//! ([`Prepared::select`]). Encoding each candidate alone took nine passes
//! over the whole matrix (the maxima, two histograms, the ties, the
//! collection, the mass, the dense maxima); a candidate whose error is
//! estimated on 1 row of tiles in 8 spent most of its time in them.

use super::EncodeError;
use radiosity_bakefile::codec::{distinct_channels, TILE};
use rayon::prelude::*;

/// Buckets of one 16-bit digit of the keys.
const DIGIT: usize = 1 << 16;

/// Whether a transfer entry can be encoded: finite and non-negative.
fn valid(v: f32) -> bool {
    v.is_finite() && v >= 0.0
}

/// One chunk of a channel's entries, summarised in one pass.
struct Chunk {
    /// The entries' sum, f64, in order.
    sum: f64,
    /// The largest entry (+0 for none above 0).
    max: f32,
    /// Whether any entry is not [`valid`].
    bad: bool,
}

impl Chunk {
    fn of(k: &[f32]) -> Chunk {
        let mut sum = 0.0f64;
        for &v in k {
            sum += v as f64;
        }
        // Separate loops, so that the branch-free ones vectorise.
        let bad = k.iter().fold(false, |b, &v| b | !valid(v));
        let max = k.iter().fold(0.0f32, |m, &v| if v > m { v } else { m });
        Chunk { sum, max, bad }
    }
}

/// Where the top `count` keys end: every key above `key`, and the first
/// `ties` entries (row-major) whose key equals it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Threshold {
    key: u32,
    ties: u64,
}

/// A candidate's sparse positions (CSR) and what is left to its dense part.
pub(super) struct Selection {
    /// `n + 1` row starts into `cols` (all 0 without a sparse part).
    pub row_ptr: Vec<u32>,
    /// Each row's selected columns, ascending.
    pub cols: Vec<u32>,
    /// Per distinct channel, the largest value not selected.
    pub dense_max: Vec<f32>,
}

/// One matrix's shared encoding work (module doc). The histograms are made
/// when first needed and kept: a single encoding pays what it did alone,
/// the choice's candidates share them.
pub(super) struct Prepared<'a> {
    pub t: [&'a [f32]; 3],
    pub n: usize,
    /// The distinct channels ([`distinct_channels`]): 1 for a grey matrix.
    pub distinct: Vec<&'a [f32]>,
    /// The largest entry of each of `t`'s three channels.
    pub maxima: [f32; 3],
    /// `1 / max` of each distinct channel (0 for an all-zero one).
    inv_max: Vec<f32>,
    /// The sum of the distinct channels' entries (f64, in fixed chunks).
    pub total_mass: f64,
    /// The thresholds of the counts prepared ([`Prepared::prepare`]), by
    /// count (`None`: nothing to select).
    thresholds: Vec<(usize, Option<Threshold>)>,
}

impl<'a> Prepared<'a> {
    /// Checks the n × n row-major channels `t` (sizes, and every entry
    /// finite and non-negative) and prepares them: one pass over each
    /// distinct channel finds a bad entry, the maxima and the mass.
    pub fn new(t: [&'a [f32]; 3], n: usize) -> Result<Prepared<'a>, EncodeError> {
        for (c, ch) in t.iter().enumerate() {
            if Some(ch.len()) != n.checked_mul(n) {
                return Err(EncodeError::Size {
                    channel: c,
                    len: ch.len(),
                    n,
                });
            }
        }
        // The tile index's u16 columns and the histograms' u32 counts.
        if n > (u16::MAX as usize + 1) * TILE || n * n > u32::MAX as usize {
            return Err(EncodeError::TooManyPatches(n));
        }
        // A grey matrix's one distinct channel stands for all three (equal
        // values, so the first bad entry is channel 0's, as it would be).
        let distinct = distinct_channels(t);
        let mut dm = Vec::with_capacity(distinct.len());
        let mut total_mass = 0.0f64;
        for (c, ch) in distinct.iter().enumerate() {
            // By fixed chunks, summed in order: rayon's own `sum` splits as
            // threads steal work, so its rounding (and the report stored in
            // the file) changed from run to run.
            let chunks: Vec<Chunk> = ch.par_chunks(1 << 16).map(Chunk::of).collect();
            if chunks.iter().any(|k| k.bad) {
                let p = ch.iter().position(|v| !valid(*v)).unwrap_or(0);
                return Err(EncodeError::Entry {
                    row: p / n,
                    col: p % n,
                    channel: c,
                    value: ch[p],
                });
            }
            dm.push(chunks.iter().map(|k| k.max).fold(0.0f32, f32::max));
            // One running sum over the channels' chunks, in order.
            for k in &chunks {
                total_mass += k.sum;
            }
        }
        let maxima = std::array::from_fn(|c| dm[c.min(dm.len() - 1)]);
        let inv_max = dm
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 })
            .collect();
        Ok(Prepared {
            t,
            n,
            distinct,
            maxima,
            inv_max,
            total_mass,
            thresholds: Vec::new(),
        })
    }

    /// Row `i`'s keys into `out` (`n` long): `Σ_c t_c / max_c` summed in
    /// channel order from `+0` (so that an entry of `−0`, which the check
    /// lets through, has the key 0, not `−0`'s bit pattern, the largest of
    /// all), as its bit pattern (monotonic for non-negative floats).
    fn row_keys(&self, i: usize, out: &mut [u32]) {
        let n = self.n;
        let row = |c: usize| &self.distinct[c][i * n..(i + 1) * n];
        // One distinct channel or three (`distinct_channels`).
        if let [ia] = self.inv_max[..] {
            for (o, &x) in out.iter_mut().zip(row(0)) {
                *o = (0.0 + x * ia).to_bits();
            }
        } else {
            let (a, b, c) = (row(0), row(1), row(2));
            let [ia, ib, ic] = [self.inv_max[0], self.inv_max[1], self.inv_max[2]];
            for (j, o) in out.iter_mut().enumerate() {
                *o = (0.0 + a[j] * ia + b[j] * ib + c[j] * ic).to_bits();
            }
        }
    }

    /// Counts `bucket(key)` (below `buckets`) over every entry, in parallel
    /// over as many blocks of rows as threads.
    fn histogram(&self, buckets: usize, bucket: impl Fn(u32) -> Option<usize> + Sync) -> Vec<u64> {
        let n = self.n;
        let blocks = rayon::current_num_threads().clamp(1, n.max(1));
        let per = n.div_ceil(blocks).max(1);
        (0..blocks)
            .into_par_iter()
            .map(|b| {
                // u32: at most n² < 2^32 entries (`new`).
                let mut h = vec![0u32; buckets];
                let mut keys = vec![0u32; n];
                for i in b * per..((b + 1) * per).min(n) {
                    self.row_keys(i, &mut keys);
                    for &k in &keys {
                        if let Some(x) = bucket(k) {
                            h[x] += 1;
                        }
                    }
                }
                h
            })
            .fold(
                || vec![0u64; buckets],
                |mut a, h| {
                    for (x, y) in a.iter_mut().zip(h) {
                        *x += u64::from(y);
                    }
                    a
                },
            )
            .reduce(
                || vec![0u64; buckets],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x += y;
                    }
                    a
                },
            )
    }

    /// Finds the thresholds of all `counts` not found before and keeps
    /// them: two passes over the matrix for all of them (the choice passes
    /// every candidate's count at once).
    pub fn prepare(&mut self, counts: &[usize]) {
        let want: Vec<usize> = counts
            .iter()
            .copied()
            .filter(|&c| !self.thresholds.iter().any(|&(k, _)| k == c))
            .collect();
        let found = self.find_thresholds(&want);
        self.thresholds.extend(found);
    }

    /// The threshold of the top `count` keys: prepared, or found now
    /// (two passes) for a single encoding.
    fn threshold(&self, count: usize) -> Option<Threshold> {
        match self.thresholds.iter().find(|&&(k, _)| k == count) {
            Some(&(_, t)) => t,
            None => self.find_thresholds(&[count]).first().and_then(|&(_, t)| t),
        }
    }

    /// The thresholds of `counts` (module doc): a histogram of the nonzero
    /// keys' high 16 bits (zero keys are never selected), then one of the
    /// low 16 bits per distinct bucket the counts fall in, in one pass.
    fn find_thresholds(&self, counts: &[usize]) -> Vec<(usize, Option<Threshold>)> {
        let mut counts: Vec<usize> = counts.iter().copied().filter(|&c| c > 0).collect();
        counts.sort_unstable();
        counts.dedup();
        if counts.is_empty() || self.n == 0 {
            return counts.into_iter().map(|c| (c, None)).collect();
        }
        let high = self.histogram(DIGIT, |k| (k != 0).then_some((k >> 16) as usize));
        let nonzero: u64 = high.iter().sum();
        let mut found = Vec::new();
        // Each count's high bucket and the keys above that bucket.
        let mut pending = Vec::new();
        for count in counts {
            let wanted = (count as u64).min(nonzero);
            if wanted == 0 {
                found.push((count, None));
            } else {
                let (hb, above) = crossing(&high, wanted, 0);
                pending.push((count, wanted, hb, above));
            }
        }
        if pending.is_empty() {
            return found;
        }
        let mut slot_of = vec![u16::MAX; DIGIT];
        let mut slots = 0usize;
        for &(_, _, hb, _) in &pending {
            if slot_of[hb] == u16::MAX {
                slot_of[hb] = slots as u16;
                slots += 1;
            }
        }
        let low = self.histogram(slots * DIGIT, |k| {
            let s = slot_of[(k >> 16) as usize];
            (k != 0 && s != u16::MAX).then(|| s as usize * DIGIT + (k & 0xffff) as usize)
        });
        for (count, wanted, hb, above) in pending {
            let h = &low[slot_of[hb] as usize * DIGIT..][..DIGIT];
            let (lb, above) = crossing(h, wanted, above);
            let key = ((hb as u32) << 16) | lb as u32;
            // `above` keys are above the threshold; the rest are its ties.
            found.push((
                count,
                Some(Threshold {
                    key,
                    ties: wanted - above,
                }),
            ));
        }
        found
    }

    /// The top `count` entries by key (ties in row-major order)
    /// and the largest value of each distinct channel left out of them, in
    /// one pass over the matrix (and a second over the rows holding ties
    /// at the threshold, usually none).
    pub fn select(&self, count: usize) -> Selection {
        let n = self.n;
        let ch = self.distinct.len();
        let Some(th) = self.threshold(count) else {
            return Selection {
                row_ptr: vec![0; n + 1],
                cols: Vec::new(),
                dense_max: self.maxima[..ch].to_vec(),
            };
        };
        // Each row's columns above the threshold, its ties, and the maxima
        // of the entries below.
        let row_max = |i: usize, keys: &[u32], keep: &[bool]| -> [f32; 3] {
            row_max(&self.distinct, n, i, keys, th.key, keep)
        };
        let mut rows: Vec<(Vec<u32>, u64, [f32; 3])> = (0..n)
            .into_par_iter()
            .map_init(
                || vec![0u32; n],
                |keys, i| {
                    self.row_keys(i, keys);
                    let mut cols = Vec::new();
                    let mut ties = 0u64;
                    for (j, &k) in keys.iter().enumerate() {
                        if k > th.key {
                            cols.push(j as u32);
                        }
                        ties += u64::from(k == th.key);
                    }
                    let m = row_max(i, keys, &[]);
                    (cols, ties, m)
                },
            )
            .collect();
        // The ties taken, first rows first; rows with ties read again.
        let mut left = th.ties;
        let allowed: Vec<(usize, u64)> = rows
            .iter()
            .enumerate()
            .filter(|r| r.1 .1 > 0)
            .map(|(i, r)| {
                let a = r.1.min(left);
                left -= a;
                (i, a)
            })
            .collect();
        let redone: Vec<(usize, Vec<u32>, [f32; 3])> = allowed
            .par_iter()
            .map_init(
                || vec![0u32; n],
                |keys, &(i, a)| {
                    self.row_keys(i, keys);
                    let mut cols = Vec::new();
                    let mut taken = 0u64;
                    // The ties left out, by column.
                    let mut out = vec![false; n];
                    for (j, &k) in keys.iter().enumerate() {
                        if k > th.key || (k == th.key && taken < a) {
                            taken += u64::from(k == th.key);
                            cols.push(j as u32);
                        } else if k == th.key {
                            out[j] = true;
                        }
                    }
                    let m = row_max(i, keys, &out);
                    (i, cols, m)
                },
            )
            .collect();
        for (i, cols, m) in redone {
            rows[i].0 = cols;
            rows[i].2 = m;
        }
        let mut row_ptr = Vec::with_capacity(n + 1);
        row_ptr.push(0u32);
        let mut cols = Vec::with_capacity(rows.iter().map(|r| r.0.len()).sum());
        let mut dense_max = vec![0.0f32; ch];
        for (r, _, m) in rows {
            cols.extend_from_slice(&r);
            row_ptr.push(cols.len() as u32);
            for (d, &x) in dense_max.iter_mut().zip(&m) {
                *d = d.max(x);
            }
        }
        Selection {
            row_ptr,
            cols,
            dense_max,
        }
    }
}

/// The bucket of the histogram `h` (counted from the top, after `above`
/// keys in higher buckets) where the running count reaches `wanted`, and
/// the keys above it.
fn crossing(h: &[u64], wanted: u64, mut above: u64) -> (usize, u64) {
    for b in (0..h.len()).rev() {
        if above + h[b] >= wanted {
            return (b, above);
        }
        above += h[b];
    }
    (0, above)
}

/// The largest value of each of `distinct`'s rows `i` whose key is below
/// `threshold` or, where `also` is not empty, marked in it (the ties left
/// to the dense part).
fn row_max(
    distinct: &[&[f32]],
    n: usize,
    i: usize,
    keys: &[u32],
    threshold: u32,
    also: &[bool],
) -> [f32; 3] {
    let mut m = [0.0f32; 3];
    for (mc, ch) in m.iter_mut().zip(distinct) {
        let row = &ch[i * n..(i + 1) * n];
        *mc = if also.is_empty() {
            row.iter()
                .zip(keys)
                .map(|(&v, &k)| if k < threshold { v } else { 0.0 })
                .fold(0.0f32, f32::max)
        } else {
            row.iter()
                .zip(keys)
                .zip(also)
                .map(|((&v, &k), &a)| if k < threshold || a { v } else { 0.0 })
                .fold(0.0f32, f32::max)
        };
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition of the sparse ranking key of an entry: `Σ_c t_c / max_c` (f32, in channel
    /// order), as its bit pattern (monotonic for non-negative floats).
    /// `channels` are the matrix's distinct channels; `inv_max` their `1/max`.
    fn sparse_key(channels: &[&[f32]], inv_max: &[f32], k: usize) -> u32 {
        let mut s = 0.0f32;
        for (ch, &im) in channels.iter().zip(inv_max) {
            s += ch[k] * im;
        }
        s.to_bits()
    }

    /// The top `count` positions by key, ties in row-major order, and the
    /// largest value left of each distinct channel, by sorting every key:
    /// the definition [`Prepared::select`] is held to.
    fn by_sorting(p: &Prepared, count: usize) -> (Vec<usize>, Vec<f32>) {
        let n = p.n;
        let mut keyed: Vec<(u32, usize)> = (0..n * n)
            .map(|k| (sparse_key(&p.distinct, &p.inv_max, k), k))
            .filter(|&(key, _)| key != 0)
            .collect();
        // Larger keys first; among equal keys, earlier positions first.
        keyed.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut top: Vec<usize> = keyed.iter().take(count).map(|&(_, k)| k).collect();
        top.sort_unstable();
        let mut chosen = vec![false; n * n];
        for &k in &top {
            chosen[k] = true;
        }
        let max = p
            .distinct
            .iter()
            .map(|ch| {
                (0..n * n)
                    .filter(|&k| !chosen[k])
                    .map(|k| ch[k])
                    .fold(0.0f32, f32::max)
            })
            .collect();
        (top, max)
    }

    fn positions(s: &Selection) -> Vec<usize> {
        let n = s.row_ptr.len() - 1;
        let mut v = Vec::new();
        for i in 0..n {
            for &j in &s.cols[s.row_ptr[i] as usize..s.row_ptr[i + 1] as usize] {
                v.push(i * n + j as usize);
            }
        }
        v
    }

    /// A matrix whose values repeat (many ties at every threshold, keys in
    /// few high buckets), with zeros, and three channels or one.
    fn matrix(n: usize, seed: u64, levels: u64) -> [Vec<f32>; 3] {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            s >> 33
        };
        std::array::from_fn(|_| {
            (0..n * n)
                .map(|_| {
                    let r = next();
                    if r % 5 == 0 {
                        0.0
                    } else if r % 23 == 1 {
                        // Negative zeros (valid entries) and subnormals,
                        // whose keys may round to 0 (never selected).
                        if r % 2 == 0 {
                            -0.0
                        } else {
                            f32::from_bits(1 + (r % 1000) as u32)
                        }
                    } else {
                        // Values spread over several octaves.
                        (1 + r % levels) as f32 * 2f32.powi((r / levels % 7) as i32 - 3)
                    }
                })
                .collect()
        })
    }

    #[test]
    fn select_equals_sorting_every_key() {
        for (n, levels) in [(37usize, 3u64), (64, 1000), (50, 1)] {
            let m = matrix(n, n as u64, levels);
            let grey = [&m[0][..], &m[0][..], &m[0][..]];
            let rgb = [&m[0][..], &m[1][..], &m[2][..]];
            for t in [grey, rgb] {
                let mut p = Prepared::new(t, n).unwrap();
                let counts: Vec<usize> = [0, 1, 7, n, n * n / 10, n * n / 3, n * n].to_vec();
                // Every count's threshold from one pass ...
                p.prepare(&counts);
                for &count in &counts {
                    let s = p.select(count);
                    let (top, max) = by_sorting(&p, count);
                    assert_eq!(positions(&s), top, "n {n}, levels {levels}, count {count}");
                    assert_eq!(s.dense_max, max, "n {n}, levels {levels}, count {count}");
                    // ... equal to each count's alone.
                    let alone = Prepared::new(t, n).unwrap();
                    assert_eq!(positions(&alone.select(count)), top);
                }
            }
        }
    }

    #[test]
    fn new_checks_sizes_and_entries() {
        let mut t = [0.25f32; 36];
        t[14] = f32::INFINITY;
        let err = Prepared::new([&t[..], &t[..], &t[..]], 6).err().unwrap();
        assert_eq!(
            err,
            EncodeError::Entry {
                row: 2,
                col: 2,
                channel: 0,
                value: f32::INFINITY
            }
        );
        let ok = [0.25f32; 36];
        let err = Prepared::new([&ok[..], &ok[..], &t[..]], 6).err().unwrap();
        assert!(
            matches!(err, EncodeError::Entry { channel: 2, .. }),
            "{err:?}"
        );
        let err = Prepared::new([&ok[..], &ok[..35], &ok[..]], 6)
            .err()
            .unwrap();
        assert!(matches!(
            err,
            EncodeError::Size {
                channel: 1,
                len: 35,
                n: 6
            }
        ));
        // The mass in order and the maxima.
        let mut v = [1.0f32; 36];
        v[35] = 3.0;
        let p = Prepared::new([&ok[..], &ok[..], &v[..]], 6).unwrap();
        assert_eq!(p.maxima, [0.25, 0.25, 3.0]);
        assert_eq!(p.total_mass, 2.0 * 9.0 + 38.0);
    }
}

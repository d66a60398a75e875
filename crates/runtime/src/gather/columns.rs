//! Which columns of `B0` a product reads: groups of 4 columns (one block
//! column of a tile) that are non-zero in some channel, by tile column, or
//! those less the negligible ones ([`ActiveColumns::culled`]); and `B0`
//! re-laid by active group for the vector kernels. A leaf of the gather:
//! the codecs' rows and the sparse part read these, and nothing here reads
//! them.

/// Column groups of `B0` that take part in a product: group `g` covers
/// columns `4g..4g + 4`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ActiveColumns {
    /// Per tile column: bit `l` set when its group `l` is active, that is
    /// some channel of `B0` is non-zero in its 4 columns (a tile has at
    /// most 64 groups: `MAX_TILE / 4`); a tile column is active when its
    /// mask is not 0. The gather walks the set bits instead of testing
    /// every group, whose pattern branch predictors miss.
    pub mask: Vec<u64>,
    /// Groups active, for reports.
    pub active_groups: usize,
    /// The active tile columns (mask not 0), ascending: a row of tiles
    /// visits these, not all its stored tiles, so that a gather with few
    /// active columns costs in proportion to them.
    pub tiles: Vec<u32>,
}

impl ActiveColumns {
    /// The active groups of `b0` (every column when `all`).
    pub fn of(b0: [&[f32]; 3], tile: usize, all: bool) -> ActiveColumns {
        let n = b0[0].len();
        let groups = n.div_ceil(4);
        let group: Vec<bool> = (0..groups).map(|g| all || group_lit(b0, g)).collect();
        ActiveColumns::from_groups(&group, tile)
    }

    /// The active groups of `b0` less its negligible ones: with `weights`
    /// the column sums of `T̃` per channel ([`radiosity_bakefile::codec::Encoded::column_sums`]),
    /// group `g` carries at most `e_g = Σ_{j ∈ g} Σ_c s_cj |b0_cj|` of the
    /// product's L1 norm (`s` sums magnitudes). The groups are
    /// dropped from the smallest `e_g` up (ties by index, so the choice is
    /// deterministic) while the dropped `e_g` sum to at most `eps` times
    /// their total `E`, so `‖T̃ b0 − T̃ b0_kept‖₁ ≤ eps · E` (a bound on the
    /// product's part lost, before f32 rounding; `E ≥ ‖T̃ b0‖₁`, with
    /// equality when `T̃` and `b0` are ≥ 0, as they are but for the
    /// near-field correction's `δ`). Groups whose columns of `T̃` are all zero
    /// (`e_g = 0`) go for free. With `eps = 0`, exactly [`Self::of`]'s
    /// groups less those: the same product bit for bit (each dropped term
    /// is `0 · b`).
    pub fn culled(b0: [&[f32]; 3], tile: usize, weights: &[Vec<f64>; 3], eps: f64) -> Culled {
        let n = b0[0].len();
        let groups = n.div_ceil(4);
        let mut lit = 0usize;
        let mut mass: Vec<(f64, u32)> = Vec::new();
        for g in 0..groups {
            if !group_lit(b0, g) {
                continue;
            }
            lit += 1;
            let e: f64 = (4 * g..(4 * g + 4).min(n))
                .map(|j| {
                    (0..3)
                        .map(|c| weights[c][j] * f64::from(b0[c][j]).abs())
                        .sum::<f64>()
                })
                .sum();
            mass.push((e, g as u32));
        }
        let total: f64 = mass.iter().map(|m| m.0).sum();
        mass.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // An infinite or NaN total (an input that overflowed) culls
        // nothing but zero columns: its product is not finite either, and
        // dropping a group of infinite mass within an infinite budget
        // would turn it into zeros.
        let budget = if total.is_finite() {
            eps.max(0.0) * total
        } else {
            0.0
        };
        let mut dropped = 0.0f64;
        let mut group = vec![false; groups];
        for &(e, g) in &mass {
            // A NaN mass (a NaN in `b0`) is never dropped: it sorts last
            // and fails the comparison.
            if e == 0.0 || dropped + e <= budget {
                dropped += e;
            } else {
                group[g as usize] = true;
            }
        }
        let columns = ActiveColumns::from_groups(&group, tile);
        Culled {
            culled_groups: lit - columns.active_groups,
            dropped_mass: dropped,
            mass: total,
            columns,
        }
    }

    /// The columns of the groups flagged in `group`.
    fn from_groups(group: &[bool], tile: usize) -> ActiveColumns {
        let per_tile = (tile / 4).clamp(1, 64);
        let mask: Vec<u64> = group
            .chunks(per_tile)
            .map(|c| {
                c.iter()
                    .enumerate()
                    .fold(0, |m, (l, &a)| m | (u64::from(a) << l))
            })
            .collect();
        ActiveColumns {
            active_groups: group.iter().filter(|&&a| a).count(),
            tiles: (0..mask.len() as u32)
                .filter(|&t| mask[t as usize] != 0)
                .collect(),
            mask,
        }
    }
}

/// Whether some channel of `b0` is non-zero in group `g`'s columns.
fn group_lit(b0: [&[f32]; 3], g: usize) -> bool {
    let n = b0[0].len();
    (4 * g..(4 * g + 4).min(n)).any(|j| b0.iter().any(|c| c[j] != 0.0))
}

/// [`ActiveColumns::culled`]'s choice.
#[derive(Clone, Debug, PartialEq)]
pub struct Culled {
    /// The groups kept.
    pub columns: ActiveColumns,
    /// Groups with a non-zero `b0` that were dropped.
    pub culled_groups: usize,
    /// The dropped groups' bound on the product's L1 norm (at most `eps`
    /// times `mass`), and the bound's total `E`.
    pub dropped_mass: f64,
    pub mass: f64,
}

/// The `k` lowest bits set (all 64 from `k = 64` on).
pub(super) fn low_bits(k: usize) -> u64 {
    if k >= 64 {
        u64::MAX
    } else {
        (1u64 << k) - 1
    }
}

/// The active groups of `active` (group `g` covers columns `4g..4g + 4`;
/// tile column `tc`'s bit `l` is group `tc · tile / 4 + l`), ascending.
pub(super) fn active_groups(
    active: &ActiveColumns,
    tile: usize,
) -> impl Iterator<Item = usize> + '_ {
    let per_tile = (tile / 4).clamp(1, 64);
    active.tiles.iter().flat_map(move |&tc| {
        let mut bits = active.mask[tc as usize];
        std::iter::from_fn(move || {
            (bits != 0).then(|| {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                tc as usize * per_tile + l
            })
        })
    })
}

/// `B0` by group of 4 columns into `out`, the three channels of a group
/// side by side and zero past `n`: what the vector BC1 kernels broadcast
/// per block column, without bounds checks. Only the active groups are
/// written (the others are never read, and keep what they held).
pub(super) fn fill_b0_groups(
    b0: [&[f32]; 3],
    active: &ActiveColumns,
    tile: usize,
    out: &mut Vec<[[f32; 4]; 3]>,
) {
    let n = b0[0].len();
    out.resize(n.div_ceil(4), [[0.0; 4]; 3]);
    for g in active_groups(active, tile) {
        out[g] = std::array::from_fn(|c| {
            std::array::from_fn(|k| b0[c].get(4 * g + k).copied().unwrap_or(0.0))
        });
    }
}

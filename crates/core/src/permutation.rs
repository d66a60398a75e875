//! A permutation of patches: the reordering (docs/design.md bake step 5) that the
//! bake applies to rows and columns of the transfer matrix and the run time
//! applies once, at load, to the per-patch data.

use rayon::prelude::*;
use serde::Serialize;

/// Why a list of indices is not a permutation.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PermutationError {
    #[error("permutation entry {entry} out of range for {n} patches")]
    OutOfRange { entry: u32, n: usize },
    #[error("permutation lists patch {0} twice")]
    Repeated(u32),
}

/// A permutation of `n` patches: `order[new] = old`, `inverse[old] = new`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Permutation {
    pub order: Vec<u32>,
    pub inverse: Vec<u32>,
}

impl Permutation {
    /// The identity on `n` patches.
    pub fn identity(n: usize) -> Permutation {
        let order: Vec<u32> = (0..n as u32).collect();
        Permutation {
            inverse: order.clone(),
            order,
        }
    }

    /// The permutation with `order[new] = old`; an error unless `order`
    /// holds every index below its length exactly once.
    pub fn from_order(order: Vec<u32>) -> Result<Permutation, PermutationError> {
        let n = order.len();
        let mut inverse = vec![u32::MAX; n];
        for (new, &old) in order.iter().enumerate() {
            let slot = inverse
                .get_mut(old as usize)
                .ok_or(PermutationError::OutOfRange { entry: old, n })?;
            if *slot != u32::MAX {
                return Err(PermutationError::Repeated(old));
            }
            *slot = new as u32;
        }
        Ok(Permutation { order, inverse })
    }

    pub fn len(&self) -> usize {
        self.order.len()
    }

    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// `P M Pᵀ` for a row-major n × n matrix: `out[i][j] = m[order[i]][order[j]]`.
    pub fn apply_symmetric(&self, m: &[f32], n: usize) -> Vec<f32> {
        assert_eq!(self.order.len(), n, "permutation size");
        assert_eq!(m.len(), n * n, "matrix size");
        let mut out = vec![0.0f32; n * n];
        out.par_chunks_mut(n.max(1))
            .zip(self.order.par_iter())
            .for_each(|(row, &old_i)| {
                let src = &m[old_i as usize * n..(old_i as usize + 1) * n];
                for (o, &old_j) in row.iter_mut().zip(&self.order) {
                    *o = src[old_j as usize];
                }
            });
        out
    }

    /// `P v`: `out[new] = v[order[new]]` (per-patch data into the new order).
    pub fn apply_vec<T: Copy>(&self, v: &[T]) -> Vec<T> {
        assert_eq!(self.order.len(), v.len(), "vector size");
        self.order.iter().map(|&old| v[old as usize]).collect()
    }

    /// `Pᵀ v`: back from the new order to the original one.
    pub fn unapply_vec<T: Copy>(&self, v: &[T]) -> Vec<T> {
        assert_eq!(self.inverse.len(), v.len(), "vector size");
        self.inverse.iter().map(|&new| v[new as usize]).collect()
    }

    /// First `self`, then `then` (applied to the already reordered data):
    /// `order[new] = self.order[then.order[new]]`.
    pub fn then(&self, then: &Permutation) -> Permutation {
        assert_eq!(self.len(), then.len(), "permutation sizes");
        let order: Vec<u32> = then.order.iter().map(|&k| self.order[k as usize]).collect();
        Permutation::from_order(order).expect("a composition of permutations is a permutation")
    }
}

// Squared Euclidean distances between the rows of a feature matrix, for the
// greedy nearest-neighbour reordering (crates/bake/src/reorder.rs). The CPU reference is
// `reorder::cpu_distances`, which computes the same quantity in f64.
//
// X is n x d, row-major: row i is the feature vector of patch i (its row of
// the transfer matrix T, the three colour channels concatenated). The kernel
// computes one batch of `rows` output rows starting at `row0`:
//
//     D[i - row0, k] = sum_x (X[i, x] - X[k, x])^2,   row0 <= i < row0 + rows.
//
// The differences are formed directly rather than through the Gram matrix
// (|a|^2 + |b|^2 - 2 a.b): the rows that matter most to the greedy search
// are the nearly identical ones, whose distance the Gram form loses to
// cancellation in f32.
//
// Tiling: a work-group computes a TILE x TILE block of D; both operands are
// staged through local memory TILE columns of X at a time, so each X value
// read from global memory is used TILE times. D is symmetric: work-groups
// whose block lies strictly below the diagonal (in absolute row indices)
// return at once, uniformly for the whole group, and the host mirrors the
// upper triangle. OpenCL 1.2 only: no atomics, explicit local size
// TILE x TILE (TILE is defined by the host: 16, or 8 on devices with small
// work-groups).

#ifndef TILE
#define TILE 16
#endif

__kernel void pair_distances(__global const float *x,
                             const uint n,
                             const uint d,
                             const uint row0,
                             const uint rows,
                             __global float *out)
{
    const uint li = get_local_id(1);
    const uint lk = get_local_id(0);
    const uint gi = get_group_id(1) * TILE; // first batch row of the block
    const uint gk = get_group_id(0) * TILE; // first column of the block
    // Blocks strictly below the diagonal are not computed: the host copies
    // them from the mirrored block above it. Such a group runs no iteration
    // of the loop below and writes nothing; the test is the same for every
    // work-item of the group, and the barriers stay outside any branch
    // (OpenCL 1.2 section 3.4.3: all work-items of a group reach each
    // barrier, or none does).
    const int skip = gk + TILE <= row0 + gi;
    const uint x_end = skip ? 0 : d;

    __local float a[TILE][TILE + 1]; // rows i of this block, TILE columns of X
    __local float b[TILE][TILE + 1]; // rows k of this block

    const uint i = row0 + gi + li;
    const uint k = gk + lk;
    float acc = 0.0f;
    for (uint x0 = 0; x0 < x_end; x0 += TILE) {
        // Work-item (li, lk) loads column x0 + lk of rows gi + li and gk + li.
        const uint col = x0 + lk;
        const uint ri = row0 + gi + li;
        const uint rk = gk + li;
        a[li][lk] = (ri < row0 + rows && ri < n && col < d) ? x[(size_t)ri * d + col] : 0.0f;
        b[li][lk] = (rk < n && col < d) ? x[(size_t)rk * d + col] : 0.0f;
        barrier(CLK_LOCAL_MEM_FENCE);
        for (uint c = 0; c < TILE; ++c) {
            const float diff = a[li][c] - b[lk][c];
            acc = fma(diff, diff, acc);
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (!skip && gi + li < rows && i < n && k < n) {
        out[(size_t)(gi + li) * n + k] = acc;
    }
}

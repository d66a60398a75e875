// Tiled single-precision matrix product for the transfer stage:
//
//     C = D + alpha * A * B        (use_d == 1)
//     C = C + alpha * A * B        (use_d == 2: an update in place)
//     C =     alpha * A * B        (use_d == 0)
//
// for row-major matrices whose sizes are multiples of the tile size TS (the
// host pads with zeros, crates/bake/src/gemm.rs). The whole-matrix products of the
// series (square N x N, alpha = 1) use a_off = b_off = c_off = 0 and
// lda = ldb = ldc = n, kt = n / TS; the blocked LU solve
// (crates/bake/src/solve.rs) passes sub-matrices of larger ones: A starts at
// element a_off with row pitch lda (rows of C x kt * TS), B at b_off with
// pitch ldb (kt * TS x columns of C), C (and D) at c_off with pitch ldc;
// the grid is one work-group per tile of C. The CPU reference is faer's
// matrix product in f64 (`gemm::reference_product` in crates/bake/src/gemm.rs).
//
// Work decomposition (the classic register-blocked SGEMM, after Goto & van
// de Geijn, "Anatomy of High-Performance Matrix Multiplication", ACM TOMS
// 34(3), 2008, and the GPU form of the same in Volkov & Demmel, "Benchmarking
// GPUs to tune dense linear algebra", SC 2008):
// - a work-group owns one TS x TS tile of C and walks the K dimension in
//   blocks of TS: it copies the A block and the B block into local memory
//   (on a CPU this is BLIS's "packing": contiguous, cache-resident panels),
//   then every work-item multiplies from local memory;
// - a work-item owns micro-tiles of MR rows x NR columns of C, held as MR x
//   (NR / VW) vectors of VW floats (float4 on a GPU, float16 on an AVX-512
//   CPU) so that each step of the K loop is one broadcast of an A element and
//   NR / VW vector FMAs per row: MR * NR / VW independent accumulators hide
//   the FMA latency and keep the loads per FMA below one;
// - when the work-group has fewer work-items than micro-tiles (on a CPU,
//   where a work-group runs on one thread and its work-items run one after
//   the other, the best local size is small), each work-item loops over
//   RM x RN micro-tiles.
//
// Accumulation order (what bounds the rounding error): each micro-tile is
// summed over one K block of TS terms with fma into fresh accumulators, and
// the block sums are added to running totals, so every output is a sum of
// at most TS + N / TS rounded terms instead of N (blocked summation; Higham,
// "Accuracy and Stability of Numerical Algorithms", 2nd ed., section 4.2).
// For the non-negative matrices of the transfer stage this bounds the
// relative error of every entry by about (TS + N / TS) * 2^-24.
//
// Zero tiles (whole-matrix products only: use_flags requires zero offsets
// and pitches n): flags_a[bi * NT + kb] (and flags_b[kb * NT + bj]) is 0
// when the TS x TS tile (bi, kb) of A (tile (kb, bj) of B) is all zeros;
// such K blocks contribute exactly zero and are skipped: neither loaded nor
// multiplied.
// The barriers stay unconditional (OpenCL 1.2, section 3.4.3: a barrier must
// be reached by all work-items of a group or by none; PoCL also rejects
// barriers under a uniform branch).
//
// Epilogue: besides C, every work-group g = bi * (groups along x) + bj
// writes
// - flags_c[g]: whether its tile of C has a non-zero entry (the operand
//   flags of the next product, at no extra pass over C);
// - stats[2 * g]: the largest ratio t / c over its tile, where t is the
//   entry of alpha * A * B and c the entry of C (0 where c == 0), or +INF when any
//   entry of C is not finite. With use_d this is the size of the term just
//   added relative to the sum: the host's convergence test and its
//   non-finite detector;
// - stats[2 * g + 1]: the number of K blocks it multiplied (not skipped).
//
// Compile-time parameters (-D, chosen by the host from the device's limits,
// `gemm::GemmConfig`): TS, MR, NR, VW (4, 8 or 16), LX, LY (local size),
// LAYOUT (below), KU (unroll factor of the K loop), KB (the K sub-block
// held in local memory). The host checks that TS is a multiple of 4, of
// MR * LY and of NR * LX, NR a multiple of VW, and KB a multiple of 4
// dividing TS; KB < TS only where a work-item owns one micro-tile (RM = RN
// = 1, the GPU forms).
//
// K sub-blocks (KB < TS): a GPU's local memory (48 KiB a work-group on
// NVIDIA's OpenCL) cannot hold two 128 x 128 blocks, and a 128 x 128 tile
// with 8 x 8 outputs per work-item is what reaches a useful share of a
// large GPU's FMA rate (Volkov & Demmel; CLBlast's tuned NVIDIA
// configurations). The A and B blocks of one TS block of K are then
// copied KB columns (rows) at a time; the accumulators still run over the
// whole TS block before joining the running totals, so every output is
// summed in the same order as with KB = TS, bit for bit, whatever KB and
// the micro-tile are (tests/transfer.rs checks it).

#define CAT(a, b) a##b
#define XCAT(a, b) CAT(a, b)
#define floatV XCAT(float, VW)
#define vloadV XCAT(vload, VW)
#define vstoreV XCAT(vstore, VW)
#define intV XCAT(int, VW)

// Copy width: float16 where the block allows (CPUs), float4 otherwise.
#if KB % 16 == 0 && LAYOUT != 1
#define CW 16
#else
#define CW 4
#endif
#define floatC XCAT(float, CW)
#define vloadC XCAT(vload, CW)
#define vstoreC XCAT(vstore, CW)

// Vectors per micro-tile row, and micro-tiles per work-item along each axis.
#define NV (NR / VW)
#define RM (TS / (MR * LY))
#define RN (TS / (NR * LX))
#define WG (LX * LY)

// Where element (row, k) of the A block and (k, col) of the B block live in
// local memory, by LAYOUT:
// 0: both as in global memory (row-major): a plain copy (CPUs);
// 1: A transposed (k-major), so that the MR values a work-item broadcasts
//    at one k are adjacent and a GPU warp reads them without bank
//    conflicts (GPUs).
// (BLIS-style micro-panels, k-major within each MR or NR panel, measured
// slower under PoCL than the plain copy: the scattered copy cost more than
// the sequential reads saved.)
#if LAYOUT == 1
#define A_AT(row, k) ((k) * TS + (row))
#else
#define A_AT(row, k) ((row) * KB + (k))
#endif
#define B_AT(k, col) ((k) * TS + (col))

__kernel __attribute__((reqd_work_group_size(LX, LY, 1)))
void gemm(__global const float *restrict a,
          __global const float *restrict b,
          __global const float *restrict d,
          __global float *restrict c,
          __global const uchar *restrict flags_a,
          __global const uchar *restrict flags_b,
          __global uchar *restrict flags_c,
          __global float *restrict stats,
          const uint n,
          const uint use_d,
          const uint use_flags,
          const ulong a_off,
          const ulong b_off,
          const ulong c_off,
          const uint lda,
          const uint ldb,
          const uint ldc,
          const uint kt,
          const float alpha)
{
    __local float as[TS * KB];
    __local float bs[KB * TS];
    __local float red_ratio[WG];
    __local int red_nonzero[WG];

    const uint lx = get_local_id(0), ly = get_local_id(1);
    const uint lid = ly * LX + lx;
    const uint bj = get_group_id(0), bi = get_group_id(1);
    const uint nt = n / TS;

    // Running totals over K blocks (registers on a GPU, where RM = RN = 1;
    // cache-resident memory on a CPU).
    floatV tot[RM][RN][MR][NV];
    for (uint i = 0; i < RM; i++)
        for (uint j = 0; j < RN; j++)
#pragma unroll
            for (uint r = 0; r < MR; r++)
#pragma unroll
                for (uint v = 0; v < NV; v++) tot[i][j][r][v] = (floatV)(0.0f);

    uint blocks = 0;
    for (uint kb = 0; kb < kt; kb++) {
        // Uniform across the work-group. The barriers stay outside the
        // conditionals: PoCL's work-group compiler rejects barriers under
        // a branch, even a uniform one.
        const bool skip = use_flags && (flags_a[bi * nt + kb] == 0 || flags_b[kb * nt + bj] == 0);
        blocks += skip ? 0 : 1;
#if KB == TS
        // The previous block's readers are done before the tiles change.
        barrier(CLK_LOCAL_MEM_FENCE);
        // Copy the blocks in vectors of CW floats.
        if (!skip) for (uint e = lid; e < TS * TS / CW; e += WG) {
            const uint row = e / (TS / CW), col = (e % (TS / CW)) * CW;
            const floatC va = vloadC(0, a + a_off + (size_t)(bi * TS + row) * lda + kb * TS + col);
#if LAYOUT == 1
            float vs[CW];
            vstoreC(va, 0, vs);
            for (uint l = 0; l < CW; l++) as[A_AT(row, col + l)] = vs[l];
#else
            vstoreC(va, 0, as + A_AT(row, col));
#endif
            vstoreC(vloadC(0, b + b_off + (size_t)(kb * TS + row) * ldb + bj * TS + col), 0,
                    bs + B_AT(row, col));
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        if (!skip) for (uint i = 0; i < RM; i++) {
            const uint row0 = (i * LY + ly) * MR;
            for (uint j = 0; j < RN; j++) {
                const uint col0 = (j * LX + lx) * NR;
                floatV acc[MR][NV];
#pragma unroll
                for (uint r = 0; r < MR; r++)
#pragma unroll
                    for (uint v = 0; v < NV; v++) acc[r][v] = (floatV)(0.0f);
#pragma unroll KU
                for (uint k = 0; k < TS; k++) {
                    floatV bv[NV];
#pragma unroll
                    for (uint v = 0; v < NV; v++) bv[v] = vloadV(0, bs + B_AT(k, col0 + v * VW));
#pragma unroll
                    for (uint r = 0; r < MR; r++) {
                        const floatV av = (floatV)(as[A_AT(row0 + r, k)]);
#pragma unroll
                        for (uint v = 0; v < NV; v++) acc[r][v] = fma(av, bv[v], acc[r][v]);
                    }
                }
#pragma unroll
                for (uint r = 0; r < MR; r++)
#pragma unroll
                    for (uint v = 0; v < NV; v++) tot[i][j][r][v] += acc[r][v];
            }
        }
#else
        // One micro-tile per work-item (RM = RN = 1): its accumulators run
        // over the KB-wide sub-blocks of this TS block of K.
        const uint row0 = ly * MR, col0 = lx * NR;
        floatV acc[MR][NV];
#pragma unroll
        for (uint r = 0; r < MR; r++)
#pragma unroll
            for (uint v = 0; v < NV; v++) acc[r][v] = (floatV)(0.0f);
        for (uint kk = 0; kk < TS; kk += KB) {
            // The previous sub-block's readers are done.
            barrier(CLK_LOCAL_MEM_FENCE);
            if (!skip) {
                // A: TS rows of KB; B: KB rows of TS; in vectors of CW.
                for (uint e = lid; e < TS * KB / CW; e += WG) {
                    const uint row = e / (KB / CW), col = (e % (KB / CW)) * CW;
                    const floatC va =
                        vloadC(0, a + a_off + (size_t)(bi * TS + row) * lda + kb * TS + kk + col);
#if LAYOUT == 1
                    float vs[CW];
                    vstoreC(va, 0, vs);
                    for (uint l = 0; l < CW; l++) as[A_AT(row, col + l)] = vs[l];
#else
                    vstoreC(va, 0, as + A_AT(row, col));
#endif
                }
                for (uint e = lid; e < KB * TS / CW; e += WG) {
                    const uint row = e / (TS / CW), col = (e % (TS / CW)) * CW;
                    vstoreC(vloadC(0, b + b_off + (size_t)(kb * TS + kk + row) * ldb + bj * TS + col), 0,
                            bs + B_AT(row, col));
                }
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            if (!skip) {
#pragma unroll KU
                for (uint k = 0; k < KB; k++) {
                    floatV bv[NV];
#pragma unroll
                    for (uint v = 0; v < NV; v++) bv[v] = vloadV(0, bs + B_AT(k, col0 + v * VW));
#pragma unroll
                    for (uint r = 0; r < MR; r++) {
                        const floatV av = (floatV)(as[A_AT(row0 + r, k)]);
#pragma unroll
                        for (uint v = 0; v < NV; v++) acc[r][v] = fma(av, bv[v], acc[r][v]);
                    }
                }
            }
        }
        if (!skip) {
#pragma unroll
            for (uint r = 0; r < MR; r++)
#pragma unroll
                for (uint v = 0; v < NV; v++) tot[0][0][r][v] += acc[r][v];
        }
#endif
    }

    // Epilogue: C = D + T (or T), and the tile's statistics.
    // Vectorised: per lane, the term / sum ratio where the sum is not zero,
    // whether any lane is not finite, whether any is not zero.
    floatV ratio_v = (floatV)(0.0f);
    int bad = 0, nonzero = 0;
    for (uint i = 0; i < RM; i++) {
        const uint row0 = (i * LY + ly) * MR;
        for (uint j = 0; j < RN; j++) {
            const uint col0 = (j * LX + lx) * NR;
            for (uint r = 0; r < MR; r++) {
                for (uint v = 0; v < NV; v++) {
                    const size_t o = c_off + (size_t)(bi * TS + row0 + r) * ldc + bj * TS + col0 + v * VW;
                    const floatV t = alpha * tot[i][j][r][v];
                    const floatV s = use_d == 2 ? vloadV(0, c + o) + t
                                   : use_d == 1 ? vloadV(0, d + o) + t : t;
                    vstoreV(s, 0, c + o);
                    const intV zero = (s == (floatV)(0.0f));
                    bad |= any(~(isfinite(s) & isfinite(t)));
                    nonzero |= any(~zero);
                    ratio_v = fmax(ratio_v, select(fabs(t) / fabs(s), (floatV)(0.0f), zero));
                }
            }
        }
    }
    float ratio = 0.0f;
    {
        float lanes[VW];
        vstoreV(ratio_v, 0, lanes);
        for (uint l = 0; l < VW; l++) ratio = fmax(ratio, lanes[l]);
    }
    if (bad) ratio = INFINITY;
    red_ratio[lid] = ratio;
    red_nonzero[lid] = nonzero;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {
        for (uint l = 1; l < WG; l++) {
            ratio = fmax(ratio, red_ratio[l]);
            nonzero |= red_nonzero[l];
        }
        const uint g = bi * get_num_groups(0) + bj;
        // A non-finite entry counts as non-zero, so that nothing downstream
        // skips it silently.
        flags_c[g] = (uchar)(nonzero || isinf(ratio));
        stats[2 * g] = ratio;
        stats[2 * g + 1] = (float)blocks;
    }
}

// flags[ti * NT + tj] = whether the TS x TS tile (ti, tj) of the N x N
// row-major matrix m has an entry other than zero (NaN counts as non-zero).
// One work-item per tile; the host launches NT x NT work-items with local
// size 1 x 1, which is cheap next to the products (N^2 reads once per
// operand). CPU reference: `gemm::tile_flags_cpu`.
__kernel void tile_flags(__global const float *restrict m, __global uchar *restrict flags,
                         const uint n)
{
    const uint tj = get_global_id(0), ti = get_global_id(1);
    const uint nt = n / TS;
    uint any = 0;
    for (uint r = 0; r < TS && !any; r++) {
        __global const float *row = m + (size_t)(ti * TS + r) * n + tj * TS;
        for (uint k = 0; k < TS; k++) any |= (row[k] != 0.0f);
    }
    flags[ti * nt + tj] = (uchar)any;
}

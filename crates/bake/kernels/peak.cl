// The device's f32 FMA rate, for the benchmarks' "fraction of peak": every
// work-item runs CHAINS independent chains of VW-wide fused multiply-adds
// a <- fma(a, m, c), `iterations` times, and writes the sum of its chains'
// lanes so that nothing can be left out. Independent chains hide the FMA
// latency (4 cycles, two pipes on a CPU core: 8 chains; a GPU hides it
// with other warps). The CPU reference is `peak::reference` in
// crates/bake/src/peak.rs, in the same order (contraction off, fma exact
// in both), so the sums agree bit for bit.
//
// Build options: -D VW=<4, 8 or 16>.

#pragma OPENCL FP_CONTRACT OFF

#define CHAINS 8
#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
typedef CAT(float, VW) vec;
#define VLOAD CAT(vload, VW)
#define VSTORE CAT(vstore, VW)

kernel void fma_peak(global float* out, uint iterations, float m, float c)
{
    uint gid = get_global_id(0);
    vec a[CHAINS];
    for (int k = 0; k < CHAINS; ++k) {
        float lanes[VW];
        for (int l = 0; l < VW; ++l)
            lanes[l] = (float)((gid * CHAINS + k) * VW + l) * (1.0f / 1048576.0f);
        a[k] = VLOAD(0, lanes);
    }
    vec vm = (vec)(m), vc = (vec)(c);
    for (uint i = 0; i < iterations; ++i) {
#pragma unroll
        for (int k = 0; k < CHAINS; ++k) a[k] = fma(a[k], vm, vc);
    }
    float s = 0.0f;
    for (int k = 0; k < CHAINS; ++k) {
        float lanes[VW];
        VSTORE(a[k], 0, lanes);
        for (int l = 0; l < VW; ++l) s += lanes[l];
    }
    out[gid] = s;
}

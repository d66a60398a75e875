// The nearest triangle each ray meets: one work-item per segment o + t d,
// t in (0, 1], over the scene's four-wide BVH. It writes the hit's
// leaf-order triangle index (0xffffffff for none) and t.
//
// This is `Bvh4::closest_hit` of crates/core/src/bvh4.rs step by step, in
// f64 with contraction off, so that every arithmetic result is the CPU's
// bit for bit (OpenCL's double +, -, *, / are correctly rounded, as
// Rust's are): the same boxes pass, children are visited in the same
// order (a stable insertion sort, as Rust's `sort_unstable` is for four
// elements), a leaf's triangles are tested with the same Moeller-Trumbore
// (`bvh::intersect`) and a hit replaces the best only when strictly
// nearer. The host (crates/bake/src/trace.rs) classifies the hits (back
// face, owner piece) on the CPU with the reference's own code.
//
// Build options: -D STACK4=<3 * depth + 4> (the traversal stack; the host
// derives it from the BVH's depth, as bvh4.rs's STACK4 bounds it).

#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#pragma OPENCL FP_CONTRACT OFF

#define EDGE_EPS 1e-5
#define LEAF 0x80000000u
#define NONE 0xffffffffu

// bvh4::Node4 (repr(C), align 64: 128 bytes).
typedef struct {
    float lo[3][4];
    float hi[3][4];
    uint child[4];
    uint valid;
    uint pad[3];
} Node4;

// bvh::Node.
typedef struct {
    float min[3]; uint left;
    float max[3]; uint count;
} Node;

// bvh::Tri.
typedef struct {
    float v0[3]; uint dir;
    float v1[3]; uint patch;
    float v2[3]; uint pad2;
} Tri;

// bvh::slab: the segment's entry into a binary node's box, or -1 when it
// misses (entries are >= 0).
static double slab(global const Node* n, const double o[3], const double inv[3])
{
    double t0 = 0.0, t1 = 1.0;
    for (int k = 0; k < 3; ++k) {
        double a = ((double)n->min[k] - o[k]) * inv[k];
        double b = ((double)n->max[k] - o[k]) * inv[k];
        // Rust's f64::min / max ignore a NaN operand.
        double lo = isnan(a) ? b : (isnan(b) ? a : (a < b ? a : b));
        double hi = isnan(a) ? b : (isnan(b) ? a : (a > b ? a : b));
        t0 = isnan(lo) ? t0 : (lo > t0 ? lo : t0);
        t1 = isnan(hi) ? t1 : (hi < t1 ? hi : t1);
    }
    return t0 <= t1 ? t0 : -1.0;
}

// bvh::intersect.
static double intersect(global const Tri* tr, const double o[3], const double d[3])
{
    double v0[3] = {(double)tr->v0[0], (double)tr->v0[1], (double)tr->v0[2]};
    double e1[3] = {(double)tr->v1[0] - v0[0], (double)tr->v1[1] - v0[1], (double)tr->v1[2] - v0[2]};
    double e2[3] = {(double)tr->v2[0] - v0[0], (double)tr->v2[1] - v0[1], (double)tr->v2[2] - v0[2]};
    double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    if (det == 0.0) return -1.0;
    double inv = 1.0 / det;
    double s[3] = {o[0] - v0[0], o[1] - v0[1], o[2] - v0[2]};
    double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) * inv;
    if (!(u >= -EDGE_EPS && u <= 1.0 + EDGE_EPS)) return -1.0;
    double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
    double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
    if (v < -EDGE_EPS || u + v > 1.0 + EDGE_EPS) return -1.0;
    double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
    return (t >= 0.0 && t <= 1.0) ? t : -1.0;
}

// closest_hit: `o` (3 per ray) and `d` (3 per ray) in the BVH's shifted
// frame, the segment being o + t d; out: `leaf` and `t` per ray.
kernel void closest_hit(global const Node4* nodes4,
                        global const Node* nodes,
                        global const Tri* tris,
                        global const double* origin,
                        global const double* dir,
                        global uint* leaf_out,
                        global double* t_out,
                        uint rays)
{
    uint r = get_global_id(0);
    if (r >= rays) return;
    double o[3] = {origin[3 * r], origin[3 * r + 1], origin[3 * r + 2]};
    double d[3] = {dir[3 * r], dir[3 * r + 1], dir[3 * r + 2]};
    double inv[3] = {1.0 / d[0], 1.0 / d[1], 1.0 / d[2]};
    uint best = NONE;
    double bt = 0.0;
    uint stack_node[STACK4];
    double stack_t[STACK4];
    stack_node[0] = 0u;
    stack_t[0] = 0.0;
    int sp = 1;
    while (sp > 0) {
        --sp;
        uint node = stack_node[sp];
        if (best != NONE && stack_t[sp] > bt) continue;
        global const Node4* n = &nodes4[node];
        // test4_portable: the four children's entries and which pass.
        double t0c[4];
        uint bits = 0u;
        for (int c = 0; c < 4; ++c) {
            double t0 = 0.0, t1 = 1.0;
            for (int k = 0; k < 3; ++k) {
                double a = ((double)n->lo[k][c] - o[k]) * inv[k];
                double b = ((double)n->hi[k][c] - o[k]) * inv[k];
                double lo = a < b ? a : b;
                double hi = a > b ? a : b;
                t0 = lo > t0 ? lo : t0;
                t1 = hi < t1 ? hi : t1;
            }
            t0c[c] = t0;
            if (t0 <= t1) bits |= 1u << c;
        }
        bits &= n->valid;
        double inner_t[4];
        uint inner_c[4];
        int m = 0;
        for (int c = 0; c < 4; ++c) {
            if (!(bits & (1u << c))) continue;
            if (best != NONE && t0c[c] > bt) continue;
            uint child = n->child[c];
            if ((child & LEAF) == 0u) {
                // Stable insertion, farther first (the sort's order).
                int j = m;
                while (j > 0 && t0c[c] > inner_t[j - 1]) {
                    inner_t[j] = inner_t[j - 1];
                    inner_c[j] = inner_c[j - 1];
                    --j;
                }
                inner_t[j] = t0c[c];
                inner_c[j] = child;
                ++m;
                continue;
            }
            global const Node* ln = &nodes[child & ~LEAF];
            if (slab(ln, o, inv) < 0.0) continue;
            for (uint k = ln->left; k < ln->left + ln->count; ++k) {
                double t = intersect(&tris[k], o, d);
                if (t > 0.0 && (best == NONE || t < bt)) {
                    best = k;
                    bt = t;
                }
            }
        }
        // The farther pushed first, so the nearer is popped first; the
        // host sized STACK4 so that this never overflows.
        for (int j = 0; j < m && sp < STACK4; ++j) {
            stack_node[sp] = inner_c[j];
            stack_t[sp] = inner_t[j];
            ++sp;
        }
    }
    leaf_out[r] = best;
    t_out[r] = best == NONE ? 0.0 : bt;
}

// Form factors with visibility: one work-item per unordered patch pair
// (i, j), i < j, of a batch of rows. It writes G_ij = A_i F_ij = A_j F_ji
// (the host derives both factors, so reciprocity is exact up to f32
// rounding) and an info word `rule << 24 | rays cast`.
//
// The method and its reasons are in crates/bake/src/form_factor/contour.rs (module doc); the
// CPU reference is `form_factor::cpu_pair`, which follows this file step by
// step in f64, and the BVH layout and traversal are `bvh::Bvh` in
// crates/core/src/bvh.rs. In short, for each pair:
//   1. back-facing test both ways on the centres (f32, same operations as
//      the reference);
//   2. emitter = the smaller patch; an m x m Gauss-Legendre rule on it, m
//      adapted to the distance;
//   3. per sample x: the receiver square clipped to x's upper half space,
//      rays to R2-lattice points of the receiver against the scene's
//      triangles (the first blocked ray may prove the whole pair blocked),
//      then Lambert's exact point-to-polygon factor times the open fraction.
//
// Contraction of a*b+c into fma is off so that the discrete decisions
// (steps 1-2) are bit-identical with the reference's f32 code.

#pragma OPENCL FP_CONTRACT OFF

#define STACK 64
#define EDGE_EPS 1e-5f
#define MAX_POLY 5
#define RULE_BACKFACING 1u
#define RULE_BLOCKED 2u
#define RULE_EVALUATED 3u
#define R2_A1 3242174889u
#define R2_A2 2447445414u
#define INV_2PI 0.15915494309189535f
// Float offset of the m thresholds in the rule table (RULE_THRESHOLDS):
// MAX_SAMPLES (MAX_SAMPLES + 1) with MAX_SAMPLES = 16.
#define RULE_THRESHOLDS 272
// Most certificate checks per pair (CERT_ATTEMPTS).
#define CERT_ATTEMPTS 3u

// Layouts shared with crates/bake/src/form_factor/contour.rs (ClPatch) and crates/core/src/bvh.rs (Node,
// Tri, Cert).
typedef struct {
    float c[3]; float h;
    float n[3]; float area;
    float u[3]; uint dir;
    float v[3]; float pad0;
    float lo[3]; float pad1;
    float hi[3]; float pad2;
} Patch;

typedef struct {
    float min[3]; uint left;
    float max[3]; uint count;
} Node;

// `patch`: the patch whose square the triangle is half of, or 0xffffffff
// for a scene triangle.
typedef struct {
    float v0[3]; uint dir;
    float v1[3]; uint patch;
    float v2[3]; uint pad2;
} Tri;

// meta: vertex count (low byte) and the direction the own-box rule
// compares (second byte; 6 = none).
typedef struct {
    float v[4][3];
    float n[3]; uint meta;
} Cert;

// Square corners (-u -v), (-u +v), (+u +v), (+u -v): clockwise seen from
// the front, which makes Lambert's sum positive for a visible receiver.
constant float CU[4] = {-1.0f, -1.0f, 1.0f, 1.0f};
constant float CV[4] = {-1.0f, 1.0f, 1.0f, -1.0f};

static uint hash32(uint x)
{
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

// b's centre above a's plane by more than tol (front_f32). Reads only the
// centres and a's normal from global memory: most pairs stop here.
static int front(global const Patch* a, global const Patch* b, float tol)
{
    float dx = b->c[0] - a->c[0];
    float dy = b->c[1] - a->c[1];
    float dz = b->c[2] - a->c[2];
    float base = dx * a->n[0] + dy * a->n[1] + dz * a->n[2];
    return base > tol;
}

// Emitter samples per side: the smallest rule whose error model meets the
// tolerance, from thresholds on (side / distance)^2 (samples_for).
static uint samples_for(const Patch* e, const Patch* r, global const float* rules, uint samples)
{
    float dx = r->c[0] - e->c[0];
    float dy = r->c[1] - e->c[1];
    float dz = r->c[2] - e->c[2];
    float d2 = dx * dx + dy * dy + dz * dz;
    float side = 2.0f * e->h;
    float side2 = side * side;
    for (uint k = 1; k < samples; ++k) {
        if (side2 <= rules[RULE_THRESHOLDS + k] * d2) return k;
    }
    return samples;
}

static void point(const Patch* p, float su, float sv, float out[3])
{
    for (int q = 0; q < 3; ++q) out[q] = p->c[q] + (p->u[q] * (p->h * su) + p->v[q] * (p->h * sv));
}

static int inside(const Patch* p, const float x[3])
{
    return p->lo[0] <= x[0] && x[0] <= p->hi[0] && p->lo[1] <= x[1] && x[1] <= p->hi[1] &&
           p->lo[2] <= x[2] && x[2] <= p->hi[2];
}

static float dot3(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const float a[3], const float b[3], float c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

// Receiver square relative to x, clipped to n . R >= 0 (Sutherland-Hodgman;
// a convex quad cut by a plane keeps at most 5 vertices). clip_receiver.
static int clip_receiver(const Patch* r, const float x[3], const float n[3], float out[MAX_POLY][3])
{
    float dc[3] = {r->c[0] - x[0], r->c[1] - x[1], r->c[2] - x[2]};
    float quad[4][3];
    for (int k = 0; k < 4; ++k)
        for (int q = 0; q < 3; ++q)
            quad[k][q] = dc[q] + (r->u[q] * (r->h * CU[k]) + r->v[q] * (r->h * CV[k]));
    int m = 0;
    for (int i = 0; i < 4; ++i) {
        int p = (i + 3) % 4;
        float dcur = dot3(n, quad[i]), dprev = dot3(n, quad[p]);
        if ((dcur >= 0.0f) != (dprev >= 0.0f) && m < MAX_POLY) {
            float t = dprev / (dprev - dcur);
            for (int q = 0; q < 3; ++q) out[m][q] = quad[p][q] + (quad[i][q] - quad[p][q]) * t;
            ++m;
        }
        if (dcur >= 0.0f && m < MAX_POLY) {
            for (int q = 0; q < 3; ++q) out[m][q] = quad[i][q];
            ++m;
        }
    }
    return m;
}

// Lambert's contour sum (not yet divided by 2 pi), with the edge angle as
// atan2(|a x b|, a . b), accurate for tiny angles. lambert.
static float lambert(float poly[MAX_POLY][3], int m, const float n[3])
{
    float sum = 0.0f;
    for (int k = 0; k < m; ++k) {
        int k1 = (k + 1) % m;
        float c[3];
        cross3(poly[k], poly[k1], c);
        float cl = sqrt(dot3(c, c));
        if (cl > 0.0f) sum += atan2(cl, dot3(poly[k], poly[k1])) / cl * dot3(n, c);
    }
    return sum;
}

// Entry parameter of the segment o + t d, t in [0, 1], into a node's box
// (fmin/fmax drop the NaN of 0 * inf). slab.
static int slab(global const Node* nd, const float o[3], const float inv[3], float* entry)
{
    float t0 = 0.0f, t1 = 1.0f;
    for (int k = 0; k < 3; ++k) {
        float a = (nd->min[k] - o[k]) * inv[k];
        float b = (nd->max[k] - o[k]) * inv[k];
        t0 = fmax(t0, fmin(a, b));
        t1 = fmin(t1, fmax(a, b));
    }
    *entry = t0;
    return t0 <= t1;
}

// Moeller-Trumbore with the barycentric range widened by EDGE_EPS so that
// rays cannot slip between triangles sharing an edge. intersect.
static int intersect(global const Tri* tr, const float o[3], const float d[3], float* tout)
{
    float v0[3] = {tr->v0[0], tr->v0[1], tr->v0[2]};
    float e1[3] = {tr->v1[0] - v0[0], tr->v1[1] - v0[1], tr->v1[2] - v0[2]};
    float e2[3] = {tr->v2[0] - v0[0], tr->v2[1] - v0[1], tr->v2[2] - v0[2]};
    float p[3];
    cross3(d, e2, p);
    float det = dot3(e1, p);
    if (det == 0.0f) return 0;
    float inv = 1.0f / det;
    float s[3] = {o[0] - v0[0], o[1] - v0[1], o[2] - v0[2]};
    float u = dot3(s, p) * inv;
    if (u < -EDGE_EPS || u > 1.0f + EDGE_EPS) return 0;
    float q[3];
    cross3(s, e1, q);
    float v = dot3(d, q) * inv;
    if (v < -EDGE_EPS || u + v > 1.0f + EDGE_EPS) return 0;
    float t = dot3(e2, q) * inv;
    if (t < 0.0f || t > 1.0f) return 0;
    *tout = t;
    return 1;
}

// Any triangle crossing the segment x + t d, t in [0, 1], except the two
// patches' own squares, and hits inside a patch's own box on geometry of that patch's facing direction
// (the surface the patch stands for) or within tol of that patch's plane
// (the ray's very end). Returns its leaf index or -1.
// Bvh::any_hit with the filter of cpu_pair.
static int any_hit(global const Node* nodes, global const Tri* tris, const float o[3], const float d[3],
                   const Patch* e, const Patch* r, uint ie, uint ir, float tol)
{
    float inv[3] = {1.0f / d[0], 1.0f / d[1], 1.0f / d[2]};
    uint stack[STACK];
    int sp = 0;
    uint node = 0;
    float ta, tb;
    if (!slab(&nodes[0], o, inv, &ta)) return -1;
    for (;;) {
        global const Node* nd = &nodes[node];
        if (nd->count > 0) {
            for (uint k = nd->left; k < nd->left + nd->count; ++k) {
                float t;
                if (!intersect(&tris[k], o, d, &t)) continue;
                uint pk = tris[k].patch;
                if (pk == ie || pk == ir) continue;
                float p[3] = {o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t};
                float pe[3] = {p[0] - e->c[0], p[1] - e->c[1], p[2] - e->c[2]};
                float pr[3] = {p[0] - r->c[0], p[1] - r->c[1], p[2] - r->c[2]};
                // Same-direction exemption for scene triangles only: another
                // patch's square is never part of e or r.
                uint dir = pk == 0xffffffffu ? tris[k].dir : 6u;
                if (inside(e, p) && (dir == e->dir || dot3(pe, e->n) <= tol)) continue;
                if (inside(r, p) && (dir == r->dir || dot3(pr, r->n) <= tol)) continue;
                return (int)k;
            }
        } else {
            uint a = nd->left, b = nd->left + 1;
            int ha = slab(&nodes[a], o, inv, &ta);
            int hb = slab(&nodes[b], o, inv, &tb);
            if (ha && hb) {
                uint first = tb < ta ? b : a;
                uint second = tb < ta ? a : b;
                // The host checks the depth against STACK; never overflows.
                if (sp < STACK) stack[sp++] = second;
                node = first;
                continue;
            }
            if (ha) { node = a; continue; }
            if (hb) { node = b; continue; }
        }
        if (sp == 0) return -1;
        node = stack[--sp];
    }
}

// Whether triangle `leaf` provably blocks every segment from the emitter's
// sample hull (nodes within [-s, s] per side) to the receiver square at a hit the own-box rule
// counts: both hulls strictly on opposite sides of its certificate
// polygon's plane, the own boxes too where the directions match, and all
// 16 corner-to-corner crossings strictly inside the polygon and off both
// patches' planes. certified.
static int certified(global const Cert* certs, uint leaf, const Patch* e, float s, const Patch* r, float tol)
{
    global const Cert* c = &certs[leaf];
    // The direction the own-box rule compares (none for a patch square).
    uint dir = c->meta >> 8;
    float n[3] = {c->n[0], c->n[1], c->n[2]};
    int nv = (int)(c->meta & 0xffu);
    float v[4][3];
    for (int k = 0; k < 4; ++k)
        for (int q = 0; q < 3; ++q) v[k][q] = c->v[k][q];
    float pd = dot3(n, v[0]);
    float ep[4][3], rp[4][3], he[4], hr[4];
    for (int k = 0; k < 4; ++k) {
        point(e, CU[k] * s, CV[k] * s, ep[k]);
        point(r, CU[k], CV[k], rp[k]);
        he[k] = dot3(n, ep[k]) - pd;
        hr[k] = dot3(n, rp[k]) - pd;
    }
    float side;
    if (he[0] < -tol && he[1] < -tol && he[2] < -tol && he[3] < -tol) side = -1.0f;
    else if (he[0] > tol && he[1] > tol && he[2] > tol && he[3] > tol) side = 1.0f;
    else return 0;
    for (int k = 0; k < 4; ++k)
        if (!(hr[k] * side < -tol)) return 0;
    for (int w = 0; w < 2; ++w) {
        const Patch* p = w == 0 ? e : r;
        float want = w == 0 ? side : -side;
        if (dir != p->dir) continue;
        for (int k = 0; k < 8; ++k) {
            float qb[3] = {(k & 1) ? p->hi[0] : p->lo[0], (k & 2) ? p->hi[1] : p->lo[1],
                           (k & 4) ? p->hi[2] : p->lo[2]};
            if (!((dot3(n, qb) - pd) * want > tol)) return 0;
        }
    }
    for (int a = 0; a < 4; ++a) {
        for (int b = 0; b < 4; ++b) {
            float t = he[a] / (he[a] - hr[b]);
            float p[3];
            for (int q = 0; q < 3; ++q) p[q] = ep[a][q] + (rp[b][q] - ep[a][q]) * t;
            // Hits within tol of either patch's plane are ignored.
            float pe[3] = {p[0] - e->c[0], p[1] - e->c[1], p[2] - e->c[2]};
            float pr[3] = {p[0] - r->c[0], p[1] - r->c[1], p[2] - r->c[2]};
            if (dot3(pe, e->n) <= tol || dot3(pr, r->n) <= tol) return 0;
            for (int k = 0; k < nv; ++k) {
                int k1 = (k + 1) % nv;
                float edge[3] = {v[k1][0] - v[k][0], v[k1][1] - v[k][1], v[k1][2] - v[k][2]};
                float rel[3] = {p[0] - v[k][0], p[1] - v[k][1], p[2] - v[k][2]};
                float cr[3];
                cross3(edge, rel, cr);
                if (dot3(cr, n) <= tol * sqrt(dot3(edge, edge))) return 0;
            }
        }
    }
    return 1;
}

// One ray from x along d: 1 = open, 0 = blocked, -1 = the pair is
// certified blocked (tried on blocked rays while `attempts` lasts; an open
// ray ends the attempts).
static int cast(global const Node* nodes, global const Tri* tris, global const Cert* certs, const float x[3],
                const float d[3], const Patch* e, const Patch* r, uint ie, uint ir, float hull, float tol,
                uint use_certs, uint* rays, uint* attempts)
{
    *rays += 1;
    int hit = any_hit(nodes, tris, x, d, e, r, ie, ir, tol);
    if (hit < 0) {
        *attempts = 0;
        return 1;
    }
    if (*attempts > 0 && use_certs) {
        *attempts -= 1;
        if (certified(certs, (uint)hit, e, hull, r, tol)) return -1;
    }
    return 0;
}

// Rows row0 .. row0 + rows - 1 of the upper triangle: work-item g handles
// pair (row0 + g / n, g % n) when its column is right of the diagonal, and
// writes g_out[g], info_out[g]; other work-items write nothing.
kernel void form_factors(global const Patch* patches, uint n, uint row0, uint rows, global const Node* nodes,
                         global const Tri* tris, global const Cert* certs, uint samples, uint rays_per_pair,
                         global const float* rules, float tol, uint use_certs, global float* g_out,
                         global uint* info_out)
{
    size_t gid = get_global_id(0);
    if (gid >= (size_t)rows * n) return;
    uint i = row0 + (uint)(gid / n);
    uint j = (uint)(gid % n);
    if (j <= i) return;
    if (!front(patches + i, patches + j, tol) || !front(patches + j, patches + i, tol)) {
        g_out[gid] = 0.0f;
        info_out[gid] = RULE_BACKFACING << 24;
        return;
    }
    Patch pi = patches[i], pj = patches[j];
    uint ie = i, ir = j;
    Patch e = pi, r = pj;
    if (pj.area < pi.area) { ie = j; ir = i; e = pj; r = pi; }
    uint m = samples_for(&e, &r, rules, samples);
    // The m-point rule: (node, weight) pairs from float offset m (m - 1).
    global const float* rule = rules + m * (m - 1);
    float hull = rule[2 * (m - 1)];
    uint per_sample = (rays_per_pair + m * m - 1) / (m * m);
    float acc = 0.0f;
    uint rays = 0;
    uint attempts = CERT_ATTEMPTS;
    for (uint a = 0; a < m; ++a) {
        for (uint b = 0; b < m; ++b) {
            float su = rule[2 * a], wu = rule[2 * a + 1];
            float sv = rule[2 * b], wv = rule[2 * b + 1];
            float x[3];
            point(&e, su, sv, x);
            float xr[3] = {x[0] - r.c[0], x[1] - r.c[1], x[2] - r.c[2]};
            if (!(dot3(xr, r.n) > 0.0f)) continue;
            float poly[MAX_POLY][3];
            int np = clip_receiver(&r, x, e.n, poly);
            if (np < 3) continue;
            uint seed = hash32(ie ^ hash32(ir ^ hash32(a * m + b)));
            uint o1 = hash32(seed), o2 = hash32(seed ^ 0x9e3779b9u);
            uint kept = 0, open = 0;
            for (uint q = 0; q < per_sample; ++q) {
                float x1 = (float)((o1 + q * R2_A1) >> 8) * (1.0f / 16777216.0f);
                float x2 = (float)((o2 + q * R2_A2) >> 8) * (1.0f / 16777216.0f);
                float y[3];
                point(&r, 2.0f * x1 - 1.0f, 2.0f * x2 - 1.0f, y);
                float d[3] = {y[0] - x[0], y[1] - x[1], y[2] - x[2]};
                if (!(dot3(d, e.n) > 0.0f)) continue;
                ++kept;
                int res = cast(nodes, tris, certs, x, d, &e, &r, ie, ir, hull, tol, use_certs, &rays, &attempts);
                if (res < 0) {
                    g_out[gid] = 0.0f;
                    info_out[gid] = (RULE_BLOCKED << 24) | rays;
                    return;
                }
                open += (uint)res;
            }
            if (kept == 0) {
                // Every lattice point lies below the horizon: one ray to the
                // clipped polygon's vertex mean instead.
                float d[3] = {0.0f, 0.0f, 0.0f};
                for (int k = 0; k < np; ++k)
                    for (int q = 0; q < 3; ++q) d[q] += poly[k][q];
                for (int q = 0; q < 3; ++q) d[q] *= 1.0f / (float)np;
                kept = 1;
                int res = cast(nodes, tris, certs, x, d, &e, &r, ie, ir, hull, tol, use_certs, &rays, &attempts);
                if (res < 0) {
                    g_out[gid] = 0.0f;
                    info_out[gid] = (RULE_BLOCKED << 24) | rays;
                    return;
                }
                open += (uint)res;
            }
            if (open == 0) continue;
            acc += (wu * wv) * lambert(poly, np, e.n) * ((float)open / (float)kept);
        }
    }
    g_out[gid] = e.area * acc * INV_2PI;
    info_out[gid] = (RULE_EVALUATED << 24) | rays;
}

// Shadow rays against the scene's triangles, for the direct light on
// patches (host: crates/gl/src/direct.rs; CPU reference: core::bvh::Bvh::
// any_hit_leaf, slab and intersect, which core::direct::DirectLight's
// shadow rays answer alike). The same binary BVH (core::bvh's Node and Tri
// layouts, world coordinates), the same traversal and the same f64
// arithmetic on its f32 data: Möller–Trumbore with the barycentric range
// widened by EDGE_EPS, slab tests whose NaNs (0 · inf on a box's plane) are
// dropped as Rust's f64::min and max drop them. `precise` keeps the
// compiler from fusing multiplies and adds, so each operation rounds as the
// CPU's does. Prepended to direct.comp by the host when the bake's scene
// has triangles.

layout(std430, binding = BVH_NODE_BINDING) readonly buffer BvhNodes { uvec4 bvh_nodes[]; }; // 2 a node
layout(std430, binding = BVH_TRI_BINDING) readonly buffer BvhTris { uvec4 bvh_tris[]; };    // 3 a triangle
// [0].x: the shadow rays' lift along the normal (DirectLight::offset);
// [1 + i]: light i's ray end, xyz, and w: 0 when the end is the lifted
// point plus xyz (directional: far times the unit direction towards the
// light), 1 when it is xyz (a point or spot light's position).
layout(std430, binding = RAY_BINDING) readonly buffer Rays { dvec4 rays[]; };

const double EDGE_EPS = 1e-5LF;

// Rust's f64::min and f64::max: a NaN operand gives the other.
double min_nan(double a, double b) {
    if (isnan(a)) return b;
    if (isnan(b)) return a;
    return min(a, b);
}
double max_nan(double a, double b) {
    if (isnan(a)) return b;
    if (isnan(b)) return a;
    return max(a, b);
}

// 1 / x with 1 / ±0 = ±inf, as IEEE division gives on the CPU (GLSL leaves
// a division by zero undefined).
double reciprocal(double x) {
    if (x != 0.0LF) return 1.0LF / x;
    bool negative = (unpackDouble2x32(x).y & 0x80000000u) != 0u;
    return packDouble2x32(uvec2(0u, negative ? 0xfff00000u : 0x7ff00000u));
}

// bvh.rs slab_bounds: whether the segment o + t d, t in [0, 1], crosses
// node k's box.
bool slab(uint k, dvec3 o, dvec3 inv, out double entry) {
    uvec4 a = bvh_nodes[2u * k];
    uvec4 b = bvh_nodes[2u * k + 1u];
    dvec3 lo = dvec3(uintBitsToFloat(a.xyz));
    dvec3 hi = dvec3(uintBitsToFloat(b.xyz));
    precise double t0 = 0.0LF;
    precise double t1 = 1.0LF;
    for (int c = 0; c < 3; c++) {
        precise double p = (lo[c] - o[c]) * inv[c];
        precise double q = (hi[c] - o[c]) * inv[c];
        t0 = max_nan(t0, min_nan(p, q));
        t1 = min_nan(t1, max_nan(p, q));
    }
    entry = t0;
    return t0 <= t1;
}

// bvh.rs intersect: whether triangle k crosses the segment o + t d, t in
// [0, 1] (math.rs dot and cross, term by term).
bool crosses(uint k, dvec3 o, dvec3 d) {
    dvec3 v0 = dvec3(uintBitsToFloat(bvh_tris[3u * k].xyz));
    dvec3 v1 = dvec3(uintBitsToFloat(bvh_tris[3u * k + 1u].xyz));
    dvec3 v2 = dvec3(uintBitsToFloat(bvh_tris[3u * k + 2u].xyz));
    precise dvec3 e1 = v1 - v0;
    precise dvec3 e2 = v2 - v0;
    precise dvec3 p = dvec3(d.y * e2.z - d.z * e2.y, d.z * e2.x - d.x * e2.z, d.x * e2.y - d.y * e2.x);
    precise double det = e1.x * p.x + e1.y * p.y + e1.z * p.z;
    if (det == 0.0LF) return false;
    precise double inv = 1.0LF / det;
    precise dvec3 s = o - v0;
    precise double u = (s.x * p.x + s.y * p.y + s.z * p.z) * inv;
    if (!(u >= -EDGE_EPS && u <= 1.0LF + EDGE_EPS)) return false;
    precise dvec3 q = dvec3(s.y * e1.z - s.z * e1.y, s.z * e1.x - s.x * e1.z, s.x * e1.y - s.y * e1.x);
    precise double v = (d.x * q.x + d.y * q.y + d.z * q.z) * inv;
    if (v < -EDGE_EPS || u + v > 1.0LF + EDGE_EPS) return false;
    precise double t = (e2.x * q.x + e2.y * q.y + e2.z * q.z) * inv;
    return t >= 0.0LF && t <= 1.0LF;
}

// bvh.rs any_hit_leaf without a filter: whether any triangle crosses the
// segment o + t d, t in [0, 1]. Nearer child first, the other on a stack
// of 64 (the build bounds the depth: bvh.rs STACK).
bool any_hit(dvec3 o, dvec3 d) {
    if (bvh_tris.length() == 0) return false;
    dvec3 inv = dvec3(reciprocal(d.x), reciprocal(d.y), reciprocal(d.z));
    uint stack[64];
    int sp = 0;
    uint node = 0u;
    double ta, tb;
    if (!slab(0u, o, inv, ta)) return false;
    for (;;) {
        uvec4 a = bvh_nodes[2u * node];
        uint count = bvh_nodes[2u * node + 1u].w;
        uint left = a.w;
        if (count > 0u) {
            for (uint k = left; k < left + count; k++) {
                if (crosses(k, o, d)) return true;
            }
        } else {
            uint l = left;
            uint r = left + 1u;
            bool hl = slab(l, o, inv, ta);
            bool hr = slab(r, o, inv, tb);
            if (hl && hr) {
                if (sp < 64) stack[sp++] = tb < ta ? l : r;
                node = tb < ta ? r : l;
                continue;
            }
            if (hl) { node = l; continue; }
            if (hr) { node = r; continue; }
        }
        if (sp == 0) return false;
        node = stack[--sp];
    }
    return false;
}

// Whether the shadow ray of the point x (unit normal n, both as the bake's
// f32 sample point) towards light i meets no triangle: from x lifted along
// n to the light's ray end (core::direct::DirectLight::at_points).
bool ray_visible(int i, vec3 x, vec3 n) {
    double offset = rays[0].x;
    precise dvec3 o = dvec3(x) + dvec3(n) * offset;
    dvec4 e = rays[1 + i];
    precise dvec3 end = e.w == 0.0LF ? o + e.xyz : e.xyz;
    precise dvec3 d = end - o;
    if (e.w != 0.0LF) {
        // Towards a point or spot light the segment stops the offset short
        // of the light (DirectLight::shadow_segment): a light in a
        // surface's plane is not shadowed by it at the segment's end.
        precise double len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        if (!(len > offset)) return true;
        precise double s = 1.0LF - offset / len;
        d = d * s;
    }
    return !any_hit(o, d);
}

// The surface map evaluated per fragment: the patches and weights that
// give H at a point x of triangle t. Mirrors crates/runtime/src/surface.rs
// `weights` step by step (its CPU reference); host: crates/gl/src/surface.rs.
// Prepended to shade.frag by the host.

layout(std430, binding = 1) readonly buffer TriStart { uint tri_start[]; };    // triangles + 1
layout(std430, binding = 2) readonly buffer Pieces { uint pieces[]; };         // 3 per piece: x | y << 16, z | flags << 16, patch; then 5 per cut: piece, n (3 float bits), d
layout(std430, binding = 3) readonly buffer PatchVoxel { uint patch_voxel[]; }; // 2 per patch: x | y << 16, z
layout(std430, binding = 4) readonly buffer PatchDirection { uint patch_direction[]; };
layout(std430, binding = 5) readonly buffer Neighbours { uint neighbours[]; }; // 8 per patch, OFFSETS order

uniform vec3 map_origin;
uniform float map_voxel_size;
uniform uvec3 map_dims;
uniform uint map_triangles;
uniform uint map_pieces;
uniform uint map_cuts;

const uint NONE = 0xffffffffu;
const uint PIECE_CUT = 2u;
const int MAX_CUTS = 3; // crates/core/src/patch.rs MAX_CUTS
const int LOOKUP_PIECE = 0;
const int LOOKUP_NEAREST = 1;
const int LOOKUP_UNMAPPED = 2;

// The voxel of a piece as (z << 16 | y, x): pieces are sorted by the key
// x + dx (y + dy z), which orders them as these pairs do.
uvec2 piece_key(uint k) {
    uint xy = pieces[3u * k];
    uint z = pieces[3u * k + 1u] & 0xffffu;
    return uvec2((z << 16) | (xy >> 16), xy & 0xffffu);
}

bool key_less(uvec2 a, uvec2 b) {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
}

// surface.rs offset_slot.
uint offset_slot(int du, int dv) {
    int k = (dv + 1) * 3 + (du + 1);
    return uint(k > 4 ? k - 1 : k);
}

// The weights at x on triangle t: up to 4 (patch, weight) pairs with
// weights summing to 1; returns how they were found.
int surface_weights(uint t, vec3 x, out uvec4 patches, out vec4 weights) {
    patches = uvec4(NONE);
    weights = vec4(0.0);
    if (t >= map_triangles) return LOOKUP_UNMAPPED;
    uint start = tri_start[t];
    uint end = tri_start[t + 1u];
    if (start == end) return LOOKUP_UNMAPPED;
    vec3 g = (x - map_origin) / map_voxel_size;
    ivec3 v = ivec3(floor(g));
    uint piece = NONE;
    int how = LOOKUP_PIECE;
    if (all(greaterThanEqual(v, ivec3(0))) && all(lessThan(v, ivec3(map_dims)))) {
        uvec2 key = uvec2((uint(v.z) << 16) | uint(v.y), uint(v.x));
        uint lo = start;
        uint hi = end;
        while (lo < hi) {
            uint mid = (lo + hi) / 2u;
            if (key_less(piece_key(mid), key)) lo = mid + 1u; else hi = mid;
        }
        if (lo < end && piece_key(lo) == key) piece = lo;
    }
    if (piece == NONE) {
        // The piece whose voxel centre is nearest to x.
        how = LOOKUP_NEAREST;
        float best = 1e38;
        for (uint k = start; k < end; k++) {
            uint xy = pieces[3u * k];
            vec3 c = vec3(float(xy & 0xffffu), float(xy >> 16), float(pieces[3u * k + 1u] & 0xffffu)) + 0.5;
            vec3 d = c - g;
            float dd = dot(d, d);
            if (dd < best) { best = dd; piece = k; }
        }
    }
    // Of a piece cut by a wall (a chain of parts in one voxel), the part x
    // lies in: along the chain while x is not on the positive side of a
    // part's cut (the cuts follow the pieces in their buffer).
    uint xy0 = pieces[3u * piece];
    vec3 local = g - vec3(float(xy0 & 0xffffu), float(xy0 >> 16), float(pieces[3u * piece + 1u] & 0xffffu));
    for (int step = 0; step < MAX_CUTS; step++) {
        if (((pieces[3u * piece + 1u] >> 16) & PIECE_CUT) == 0u) break;
        uint base = 3u * map_pieces;
        uint lo = 0u;
        uint hi = map_cuts;
        while (lo < hi) {
            uint mid = (lo + hi) / 2u;
            if (pieces[base + 5u * mid] < piece) lo = mid + 1u; else hi = mid;
        }
        if (lo >= map_cuts || pieces[base + 5u * lo] != piece) break;
        uint c = base + 5u * lo;
        vec3 n = vec3(uintBitsToFloat(pieces[c + 1u]), uintBitsToFloat(pieces[c + 2u]), uintBitsToFloat(pieces[c + 3u]));
        if (dot(n, local) - uintBitsToFloat(pieces[c + 4u]) >= 0.0) break;
        piece += 1u;
    }
    uint p = pieces[3u * piece + 2u];
    if (p == NONE) return LOOKUP_UNMAPPED;
    uint pxy = patch_voxel[2u * p];
    vec3 pv = vec3(float(pxy & 0xffffu), float(pxy >> 16), float(patch_voxel[2u * p + 1u]));
    uint axis = patch_direction[p] / 2u;
    uint ua = (axis + 1u) % 3u;
    uint va = (axis + 2u) % 3u;
    float fu = clamp(g[ua] - (pv[ua] + 0.5), -0.5, 0.5);
    float fv = clamp(g[va] - (pv[va] + 0.5), -0.5, 0.5);
    int su = fu < 0.0 ? -1 : 1;
    int sv = fv < 0.0 ? -1 : 1;
    float wu = abs(fu);
    float wv = abs(fv);
    uvec4 cand = uvec4(p, neighbours[8u * p + offset_slot(su, 0)],
                       neighbours[8u * p + offset_slot(0, sv)],
                       neighbours[8u * p + offset_slot(su, sv)]);
    vec4 cw = vec4((1.0 - wu) * (1.0 - wv), wu * (1.0 - wv), (1.0 - wu) * wv, wu * wv);
    float total = 0.0;
    for (int k = 0; k < 4; k++) if (cand[k] != NONE) total += cw[k];
    int m = 0;
    for (int k = 0; k < 4; k++) {
        if (cand[k] != NONE && cw[k] > 0.0) {
            patches[m] = cand[k];
            weights[m] = cw[k] / total;
            m++;
        }
    }
    if (m == 0) { patches[0] = p; weights[0] = 1.0; }
    return how;
}

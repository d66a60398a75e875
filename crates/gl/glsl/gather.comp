// The gather H = T~ . B0 on the GPU (host: crates/gl/src/gather.rs; CPU reference:
// crates/runtime/src/gather.rs). The host adds the #version line and the defines
// TILE (the codec's tile edge, 32), PASS (0, 1 or 2: one program each),
// FORMAT (the dense part's format, numbered below) and CHANNELS (stored
// channels: 1 for a grey matrix, else 3), SPARSE (the sparse values'
// precision) and SPARSE_CHANNELS.
//
// Every entry is decoded here from the stored bytes with the CPU decoder's
// integer arithmetic and tables (crates/runtime/src/gather/palette.rs and bc6h.rs),
// never by a texture unit: GL and CPU then multiply the same f32 entries and
// differ only in the order of their f32 sums, on every driver. (Texture
// units decode BC1 differently from vendor to vendor: Mesa truncates the
// interpolated palette bytes, NVIDIA's came out ~3 log-byte steps, 3.6 %,
// from the CPU's.)
//
// Three passes, each a program of this file:
//  0. per row of tiles tr (one work-group): the input x = s o B0 of tile
//     column tr (the column scales, 1 where the matrix has none) as one
//     vec4 a column, zero past n; and the compacted list of the row's stored
//     tiles whose tile column is active this frame (tile_active, flagged by
//     the direct pass), in stored order, by a work-group prefix sum.
//  1. per row of tiles and slab of SLAB listed tiles (one work-group of
//     WARPS groups of LANES invocations): each group of 32 takes a tile at a
//     time, each invocation two 4 x 4 blocks of it (block rows br and br + 4
//     of block column bc); it accumulates its blocks' 8 rows in registers
//     over the slab's tiles; the work-group then sums them in shared memory
//     in a fixed order into the slab's partial sums of the 32 rows.
//  2. per 8 rows (one work-group, 32 invocations a row): the row's sparse
//     entries, strided over the 32, summed in a fixed tree, plus the row's
//     slab partial sums in slab order: H_i.
// Deterministic: every sum has a fixed order for a given list of active
// tile columns (skipping inactive columns changes only that order).

#define LANES 32
#define WARPS 8
#define GROUP 256

// FORMAT
#define BC1 0
#define BC4 1
#define BC6H 2
#define F16 3
#define F32 4
// SPARSE
#define SPARSE_F32 0
#define SPARSE_F16 1
#define SPARSE_RGB9E5 2

layout(local_size_x = GROUP) in;

layout(std430, binding = 0) readonly buffer RowStart { uint row_start[]; };   // tiles_per_side + 1
layout(std430, binding = 1) readonly buffer TileCol { uint tile_col[]; };     // per stored tile
layout(std430, binding = 2) readonly buffer B0 { float b0[]; };               // 3 n, channel-major
layout(std430, binding = 3) readonly buffer Active { uint tile_active[]; };   // per tile column
layout(std430, binding = 4) readonly buffer SparseRow { uint sparse_row[]; }; // n + 1
layout(std430, binding = 5) readonly buffer SparseCol { uint sparse_col[]; }; // u16 columns, 2 a word
layout(std430, binding = 6) readonly buffer SparseVal { uint sparse_val[]; }; // as SPARSE says
layout(std430, binding = 7) writeonly buffer H { float h[]; };                // 3 n, channel-major
layout(std430, binding = 8) readonly buffer Dense { uint dense[]; };          // the stored tiles
layout(std430, binding = 9) readonly buffer Offset { uint tile_offset[]; };   // bytes, per stored tile
layout(std430, binding = 10) readonly buffer ColScale { float col_scale[]; }; // n
layout(std430, binding = 11) buffer X { vec4 x[]; };                          // padded columns
layout(std430, binding = 12) buffer List { uint list[]; };                    // per row at row_start
layout(std430, binding = 13) buffer Count { uint list_count[]; };             // per row of tiles
layout(std430, binding = 14) buffer Partial { float partial[]; };             // 4 per (slab, row)
layout(std430, binding = 15) readonly buffer Table { float table[]; };        // the decoders' tables

uniform uint n;
uniform uint image_size;     // side of the dense image
uniform uint tiles_per_side;
uniform uint padded;         // tiles_per_side * TILE: rows and columns of x and partial
uniform uint slab;           // listed tiles per work-group of pass 1

#if PASS == 0

shared uint scan[GROUP];

void main() {
    uint tr = gl_WorkGroupID.x;
    uint lid = gl_LocalInvocationID.x;
    // x for tile column tr (the tile edge is at most GROUP).
    if (lid < uint(TILE)) {
        uint j = tr * uint(TILE) + lid;
        vec4 v = vec4(0.0);
        if (j < n) {
            float s = col_scale[j];
            v = vec4(b0[j] * s, b0[n + j] * s, b0[2u * n + j] * s, 0.0);
        }
        x[j] = v;
    }
    // The stored tiles of row tr in active tile columns, in stored order.
    uint first = row_start[tr];
    uint end = row_start[tr + 1u];
    uint total = 0u;
    for (uint base = first; base < end; base += uint(GROUP)) {
        uint s = base + lid;
        uint flag = (s < end && tile_active[tile_col[s]] != 0u) ? 1u : 0u;
        scan[lid] = flag;
        barrier();
        // Inclusive prefix sum (Hillis and Steele).
        for (uint off = 1u; off < uint(GROUP); off <<= 1) {
            uint add = lid >= off ? scan[lid - off] : 0u;
            barrier();
            scan[lid] += add;
            barrier();
        }
        if (flag != 0u) {
            list[first + total + scan[lid] - 1u] = s;
        }
        total += scan[GROUP - 1];
        barrier();
    }
    if (lid == 0u) {
        list_count[tr] = total;
    }
}

#elif PASS == 1

#if FORMAT == BC1
shared float lut[768]; // the value of each log byte, per channel
#endif
shared float red[GROUP * 12]; // one half of the invocations' row sums

// f16 bits (finite, non-negative) as f32, as the CPU's half_to_f32
// (runtime/gather/bc6h.rs): subnormals scaled exactly, normals rebased.
float half_value(uint hb) {
    if (hb < 0x400u) {
        return float(hb) * (1.0 / 16777216.0);
    }
    return uintBitsToFloat((hb << 13) + (112u << 23));
}

#if FORMAT == BC4
// Index t (0..15) of a BC4 block: 3 bits from bit 16 + 3 t of its 8 bytes.
uint bc4_index(uint w0, uint w1, uint t) {
    uint p = 16u + 3u * t;
    if (p >= 32u) return (w1 >> (p - 32u)) & 7u;
    if (p <= 29u) return (w0 >> p) & 7u;
    return ((w0 >> p) | (w1 << (32u - p))) & 7u;
}

// The value of index i of a block with endpoints r0, r1 in channel c: the
// CPU's tables by the interpolation's numerator (palette.rs, bc4_palette):
// t7 (8 levels, r0 > r1) and t5 (6 levels, then 0 and the top).
float bc4_value(uint c, uint r0, uint r1, uint i) {
    uint t7 = c * 3062u;
    uint t5 = t7 + 1786u;
    if (r0 > r1) {
        uint k = i == 0u ? 7u * r0 : (i == 1u ? 7u * r1 : (8u - i) * r0 + (i - 1u) * r1);
        return table[t7 + k];
    }
    if (i == 6u) return 0.0;
    if (i == 7u) return table[t5 + 1275u];
    uint k = i == 0u ? 5u * r0 : (i == 1u ? 5u * r1 : (6u - i) * r0 + (i - 1u) * r1);
    return table[t5 + k];
}
#endif

// Block (br, bc) of stored tile `slot` (th x tw texels, bw blocks a row)
// times the block's 4 columns of x, added into rows[0..4].
void add_block(uint slot, uint br, uint bc, uint bw, uint th, uint tw, vec3 xq[4],
               inout vec3 rows[4]) {
    uint k = br * bw + bc;
    uint o = tile_offset[slot];
#if FORMAT == BC1
    uint w0 = dense[o / 4u + 2u * k];
    uint w1 = dense[o / 4u + 2u * k + 1u];
    uint c0 = w0 & 0xffffu;
    uint c1 = w0 >> 16;
    uvec3 a = uvec3(c0 >> 11, (c0 >> 5) & 63u, c0 & 31u);
    uvec3 b = uvec3(c1 >> 11, (c1 >> 5) & 63u, c1 & 31u);
    // bcdec_rs's palette bytes (palette.rs, bc1_palette_bytes): 5-bit red
    // and blue, 6-bit green endpoints expanded and interpolated in integers.
    uvec3 q0 = uvec3((a.r * 527u + 23u) >> 6, (a.g * 259u + 33u) >> 6, (a.b * 527u + 23u) >> 6);
    uvec3 q1 = uvec3((b.r * 527u + 23u) >> 6, (b.g * 259u + 33u) >> 6, (b.b * 527u + 23u) >> 6);
    uvec3 q2, q3;
    if (c0 > c1) {
        uvec3 s = 2u * a + b;
        uvec3 t = a + 2u * b;
        q2 = uvec3((s.r * 351u + 61u) >> 7, (s.g * 2763u + 1039u) >> 11, (s.b * 351u + 61u) >> 7);
        q3 = uvec3((t.r * 351u + 61u) >> 7, (t.g * 2763u + 1039u) >> 11, (t.b * 351u + 61u) >> 7);
    } else {
        uvec3 s = a + b;
        q2 = uvec3((s.r * 1053u + 125u) >> 8, (s.g * 4145u + 1019u) >> 11, (s.b * 1053u + 125u) >> 8);
        q3 = uvec3(0u); // black: byte 0, exactly 0
    }
    vec3 p0 = vec3(lut[q0.r], lut[256u + q0.g], lut[512u + q0.b]);
    vec3 p1 = vec3(lut[q1.r], lut[256u + q1.g], lut[512u + q1.b]);
    vec3 p2 = vec3(lut[q2.r], lut[256u + q2.g], lut[512u + q2.b]);
    vec3 p3 = vec3(lut[q3.r], lut[256u + q3.g], lut[512u + q3.b]);
    for (uint y = 0u; y < 4u; y++) {
        for (uint c = 0u; c < 4u; c++) {
            uint idx = (w1 >> (2u * (4u * y + c))) & 3u;
            // Selections, not interpolations: the palette value itself.
            bvec3 lo = bvec3((idx & 1u) != 0u);
            vec3 v = mix(mix(p0, p1, lo), mix(p2, p3, lo), bvec3(idx >= 2u));
            rows[y] += v * xq[c];
        }
    }
#elif FORMAT == BC4
    // Channel planes of th/4 x bw blocks.
    uint plane = ((th + 3u) / 4u) * bw * 2u;
    vec3 vals[16];
    for (uint t = 0u; t < 16u; t++) vals[t] = vec3(0.0);
    for (uint c = 0u; c < uint(CHANNELS); c++) {
        uint w0 = dense[o / 4u + c * plane + 2u * k];
        uint w1 = dense[o / 4u + c * plane + 2u * k + 1u];
        uint r0 = w0 & 255u;
        uint r1 = (w0 >> 8) & 255u;
        for (uint t = 0u; t < 16u; t++) {
            float v = bc4_value(c, r0, r1, bc4_index(w0, w1, t));
#if CHANNELS == 1
            vals[t] = vec3(v);
#else
            vals[t][c] = v;
#endif
        }
    }
    for (uint y = 0u; y < 4u; y++) {
        for (uint c = 0u; c < 4u; c++) {
            rows[y] += vals[4u * y + c] * xq[c];
        }
    }
#elif FORMAT == BC6H
    // The block unpacked at load (bc6h.rs, 44 bytes): 12 u16 endpoints
    // (region 0's e0 and e1 as r, g, b, then region 1's), 16 u8 weights,
    // the u16 region mask.
    uint base = o / 4u + 11u * k;
    ivec3 e00, e01, e10, e11;
    uint ep[12];
    for (uint q = 0u; q < 6u; q++) {
        uint w = dense[base + q];
        ep[2u * q] = w & 0xffffu;
        ep[2u * q + 1u] = w >> 16;
    }
    e00 = ivec3(ep[0], ep[1], ep[2]);
    e01 = ivec3(ep[3], ep[4], ep[5]);
    e10 = ivec3(ep[6], ep[7], ep[8]);
    e11 = ivec3(ep[9], ep[10], ep[11]);
    uint mask = dense[base + 10u] & 0xffffu;
    vec3 inv = vec3(table[0], table[1], table[2]);
    for (uint y = 0u; y < 4u; y++) {
        for (uint c = 0u; c < 4u; c++) {
            uint t = 4u * y + c;
            int w = int((dense[base + 6u + t / 4u] >> (8u * (t % 4u))) & 255u);
            bool one = ((mask >> t) & 1u) != 0u;
            ivec3 e0 = one ? e10 : e00;
            ivec3 e1 = one ? e11 : e01;
            // The specification's interpolation and scaling to half bits,
            // as bcdec_rs and the CPU compute them.
            ivec3 xi = ((e0 << 6) + (e1 - e0) * w + 32) >> 6;
            uvec3 hb = uvec3((xi * 31) >> 6);
            vec3 v = vec3(half_value(hb.r), half_value(hb.g), half_value(hb.b)) * inv;
            rows[y] += v * xq[c];
        }
    }
#else
    // f16 and f32: texel-major tiles, CHANNELS values a texel; edge tiles
    // need not be multiples of 4 (the image is n wide).
    for (uint y = 0u; y < 4u; y++) {
        uint r = 4u * br + y;
        if (r >= th) break;
        for (uint c = 0u; c < 4u; c++) {
            uint col = 4u * bc + c;
            if (col >= tw) break;
            uint q = (r * tw + col) * uint(CHANNELS);
            vec3 v;
            for (uint ch = 0u; ch < 3u; ch++) {
                uint qc = q + min(ch, uint(CHANNELS) - 1u);
#if FORMAT == F32
                v[ch] = uintBitsToFloat(dense[o / 4u + qc]);
#else
                uint g = o / 2u + qc;
                uint hb = (dense[g / 2u] >> (16u * (g & 1u))) & 0xffffu;
                v[ch] = half_value(hb) * table[ch];
#endif
            }
            rows[y] += v * xq[c];
        }
    }
#endif
}

void main() {
    uint tr = gl_WorkGroupID.x;
    uint z = gl_WorkGroupID.y;
    uint lid = gl_LocalInvocationID.x;
    uint warp = lid / uint(LANES);
    uint lane = lid % uint(LANES);
    uint count = list_count[tr];
    uint first = z * slab;
    if (first >= count) {
        return; // the whole work-group: its slab has no tile this frame
    }
#if FORMAT == BC1
    for (uint k = lid; k < 768u; k += uint(GROUP)) lut[k] = table[k];
    barrier();
#endif
    uint last = min(first + slab, count);
    uint th = min(uint(TILE), image_size - tr * uint(TILE));
    uint bh = (th + 3u) / 4u;
    uint bc = lane % 8u;
    uint br0 = lane / 8u;
    vec3 lo[4];
    vec3 hi[4];
    for (uint r = 0u; r < 4u; r++) {
        lo[r] = vec3(0.0);
        hi[r] = vec3(0.0);
    }
    uint listed = row_start[tr];
    for (uint k = first + warp; k < last; k += uint(WARPS)) {
        uint slot = list[listed + k];
        uint c0 = tile_col[slot] * uint(TILE);
        uint tw = min(uint(TILE), image_size - c0);
        uint bw = (tw + 3u) / 4u;
        if (bc >= bw) continue;
        vec3 xq[4];
        for (uint c = 0u; c < 4u; c++) xq[c] = x[c0 + 4u * bc + c].rgb;
        if (br0 < bh) add_block(slot, br0, bc, bw, th, tw, xq, lo);
        if (br0 + 4u < bh) add_block(slot, br0 + 4u, bc, bw, th, tw, xq, hi);
    }
    // The slab's row sums: rows 4 br + r of every invocation with block
    // row br, summed over the block columns and the groups in that order.
    for (uint part = 0u; part < 2u; part++) {
        for (uint r = 0u; r < 4u; r++) {
            vec3 v = part == 0u ? lo[r] : hi[r];
            red[lid * 12u + 3u * r] = v.r;
            red[lid * 12u + 3u * r + 1u] = v.g;
            red[lid * 12u + 3u * r + 2u] = v.b;
        }
        barrier();
        if (lid < 48u) {
            uint rr = lid / 3u; // row within the part: block row rr / 4, row rr % 4
            uint c = lid % 3u;
            uint br = rr / 4u;
            uint r = rr % 4u;
            float s = 0.0;
            for (uint w = 0u; w < uint(WARPS); w++) {
                for (uint q = 0u; q < 8u; q++) {
                    uint from = w * uint(LANES) + br * 8u + q;
                    s += red[from * 12u + 3u * r + c];
                }
            }
            uint i = tr * uint(TILE) + 16u * part + rr;
            partial[4u * (z * padded + i) + c] = s;
        }
        barrier();
    }
}

#else // PASS == 2

#if SPARSE == SPARSE_F16
float half_value(uint hb) {
    if (hb < 0x400u) {
        return float(hb) * (1.0 / 16777216.0);
    }
    return uintBitsToFloat((hb << 13) + (112u << 23));
}
#endif

shared vec3 sums[GROUP];

// Sparse entry e's values (three channels; a grey part's one three times).
vec3 sparse_value(uint e) {
#if SPARSE == SPARSE_RGB9E5
    // Mantissas times 2^(e - 24) / scale_c (the CPU's exp_factor table).
    uint w = sparse_val[e];
    uint ex = w >> 27;
    vec3 m = vec3(float(w & 511u), float((w >> 9) & 511u), float((w >> 18) & 511u));
    return m * vec3(table[3u * ex], table[3u * ex + 1u], table[3u * ex + 2u]);
#else
    vec3 v;
    for (uint c = 0u; c < 3u; c++) {
        uint q = e * uint(SPARSE_CHANNELS) + min(c, uint(SPARSE_CHANNELS) - 1u);
#if SPARSE == SPARSE_F32
        v[c] = uintBitsToFloat(sparse_val[q]);
#else
        uint hb = (sparse_val[q / 2u] >> (16u * (q & 1u))) & 0xffffu;
        v[c] = half_value(hb) * table[c];
#endif
    }
    return v;
#endif
}

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint lane = lid % uint(LANES);
    uint i = gl_WorkGroupID.x * uint(WARPS) + lid / uint(LANES);
    vec3 acc = vec3(0.0);
    if (i < n) {
        uint end = sparse_row[i + 1u];
        for (uint e = sparse_row[i] + lane; e < end; e += uint(LANES)) {
            uint j = (sparse_col[e / 2u] >> (16u * (e & 1u))) & 0xffffu;
            acc += sparse_value(e) * x[j].rgb;
        }
    }
    sums[lid] = acc;
    barrier();
    for (uint s = uint(LANES) / 2u; s > 0u; s >>= 1) {
        if (lane < s) sums[lid] += sums[lid + s];
        barrier();
    }
    if (lane == 0u && i < n) {
        uint tr = i / uint(TILE);
        uint slabs = (list_count[tr] + slab - 1u) / slab;
        vec3 d = vec3(0.0);
        for (uint z = 0u; z < slabs; z++) {
            uint p = 4u * (z * padded + i);
            d += vec3(partial[p], partial[p + 1u], partial[p + 2u]);
        }
        vec3 v = d + sums[lid];
        h[i] = v.r;
        h[n + i] = v.g;
        h[2u * n + i] = v.b;
    }
}

#endif

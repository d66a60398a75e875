// The gather H = T~ . B0 on the GPU (host: src/gl/gather.rs; CPU reference:
// src/runtime/gather.rs). The #version line and the TILE define are added
// by the host (src/gl/mod.rs).
//
// One work-group per row of tiles, one invocation per matrix row i. The
// dense part is the BC1 (or BC4) texture of log-scaled entries, its stored tiles in
// an atlas (stored tile s at atlas tile (s % atlas_tiles_x, s / atlas_tiles_x)),
// read with texelFetch only: a filtered read would blend neighbouring
// matrix entries. Zero tiles are not stored (the tile index lists the
// stored ones); tiles whose column of B0 is zero in every channel are
// skipped (tile_active, built per frame by the host). The decoded byte x in
// [0, 1] of channel c is the entry scale_c * exp(L (x - 1)), and 0 for
// x = 0 (bakefile::codec, "Log scale"). Then the exact sparse part of row i.
// Both parts hold T' = T~ diag(1/s) with the column scales s (all 1 for a
// matrix without them: bakefile::codec, "Column scales"), so each term
// multiplies s_j B0_j, rounded as the CPU gather rounds it.

layout(local_size_x = TILE) in;

layout(binding = 0) uniform sampler2DArray atlas; // BC1: 1 RGB layer; BC4: 1 red layer per channel

layout(std430, binding = 0) readonly buffer RowStart { uint row_start[]; };
layout(std430, binding = 1) readonly buffer TileCol { uint tile_col[]; };
layout(std430, binding = 2) readonly buffer B0 { float b0[]; };          // 3 n, channel-major
layout(std430, binding = 3) readonly buffer Active { uint tile_active[]; }; // per tile column
layout(std430, binding = 4) readonly buffer SparseRow { uint sparse_row[]; };
layout(std430, binding = 5) readonly buffer SparseCol { uint sparse_col[]; };
layout(std430, binding = 6) readonly buffer SparseVal { float sparse_val[]; }; // 3 per position
layout(std430, binding = 7) writeonly buffer H { float h[]; };         // 3 n, channel-major
layout(std430, binding = 8) readonly buffer Dense { uint dense[]; };   // f16, f32: the stored tiles' bytes
layout(std430, binding = 9) readonly buffer Offset { uint tile_offset[]; }; // byte offset of each stored tile
layout(std430, binding = 10) readonly buffer ColScale { float col_scale[]; }; // n: the stored matrix multiplies s o B0

uniform uint n;
uniform uint atlas_tiles_x;
uniform vec3 scale;
uniform float log_range;
uniform uint format;     // 0 BC1, 1 BC4 (log-scaled), 2 BC6H, 3 f16, 4 f32
uniform uint layers;     // BC4: 1 (grey matrix) or 3
uniform uint channels;   // stored channels (1: grey)
uniform uint image_size; // side of the dense image

// BC1 and BC4: the decoded log bytes in [0, 1] of the three channels.
vec3 fetch(ivec2 p) {
    if (format == 0u) {
        return texelFetch(atlas, ivec3(p, 0), 0).rgb;
    }
    float x = texelFetch(atlas, ivec3(p, 0), 0).r;
    if (layers == 1u) {
        return vec3(x);
    }
    return vec3(x, texelFetch(atlas, ivec3(p, 1), 0).r, texelFetch(atlas, ivec3(p, 2), 0).r);
}

// f16 and f32: entry (r, c) of stored tile s (tw texels wide), texel-major
// with `channels` values per texel; f16 values are times `scale`'s inverse
// (the power of two they were stored multiplied by).
vec3 plain(uint s, uint r, uint c, uint tw) {
    uint t = (r * tw + c) * channels;
    vec3 v;
    for (uint k = 0u; k < 3u; k++) {
        uint q = t + min(k, channels - 1u);
        if (format == 4u) {
            v[k] = uintBitsToFloat(dense[tile_offset[s] / 4u + q]);
        } else {
            uint g = tile_offset[s] / 2u + q;
            vec2 pair = unpackHalf2x16(dense[g / 2u]);
            v[k] = ((g & 1u) == 0u ? pair.x : pair.y) / scale[k];
        }
    }
    return v;
}

void main() {
    uint tr = gl_WorkGroupID.x;
    uint r = gl_LocalInvocationID.x;
    uint i = tr * TILE + r;
    if (i >= n) {
        return;
    }
    vec3 acc = vec3(0.0);
    for (uint s = row_start[tr]; s < row_start[tr + 1u]; s++) {
        uint tc = tile_col[s];
        if (tile_active[tc] == 0u) {
            continue;
        }
        ivec2 base = ivec2(int((s % atlas_tiles_x) * TILE), int((s / atlas_tiles_x) * TILE + r));
        uint c0 = tc * TILE;
        uint w = min(uint(TILE), n - c0);
        uint tw = min(uint(TILE), image_size - c0);
        for (uint c = 0u; c < w; c++) {
            vec3 v;
            if (format <= 1u) {
                vec3 x = fetch(base + ivec2(int(c), 0));
                v = mix(vec3(0.0), scale * exp(log_range * (x - 1.0)), greaterThan(x, vec3(0.0)));
            } else if (format == 2u) {
                v = texelFetch(atlas, ivec3(base + ivec2(int(c), 0), 0), 0).rgb / scale;
            } else {
                v = plain(s, r, c, tw);
            }
            uint j = c0 + c;
            acc += v * (col_scale[j] * vec3(b0[j], b0[n + j], b0[2u * n + j]));
        }
    }
    for (uint e = sparse_row[i]; e < sparse_row[i + 1u]; e++) {
        uint j = sparse_col[e];
        vec3 v = vec3(sparse_val[3u * e], sparse_val[3u * e + 1u], sparse_val[3u * e + 2u]);
        acc += v * (col_scale[j] * vec3(b0[j], b0[n + j], b0[2u * n + j]));
    }
    h[i] = acc.r;
    h[n + i] = acc.g;
    h[2u * n + i] = acc.b;
}

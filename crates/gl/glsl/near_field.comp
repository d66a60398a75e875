// The near-field correction (host: crates/gl/src/near_field.rs; CPU reference:
// crates/runtime/src/near_field.rs; what it is: crates/bakefile/src/near_field.rs).
//
// stage 0, one invocation per receiver i: c_i = sum over its links l of
// sum_g w[l][g] * rho_p * D_p,g (p the link's neighbour, g its lit points,
// D at the points from direct.comp), summed per link in f32 as the CPU
// does; delta_i = sum_g own[i][g] * rho_i * D_i,g (how the receivers
// without a stored link see patch i, less its area shares); then the
// gather's input
// B0_i + delta_i + rho_i c_i (B0 itself stays as the direct pass wrote
// it), and the tile column of a non-zero one is flagged for the gather.
// stage 1, after the gather: H_i += c_i.
// stage 2, after stage 1: H's deviation in each of receiver i's 16 face cells,
// delta_ig = sum over its links l of u[l][g] * (B0_p + rho_p H_p) (p the
// link's neighbour), summed per link in f32 as the CPU does
// (NearFieldWeights::receiver_deviation); shade.frag adds it per pixel.

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Starts { uint starts[]; };     // n + 1
layout(std430, binding = 1) readonly buffer LinkPatch { uint link_patch[]; };
layout(std430, binding = 2) readonly buffer LinkWeights { float link_w[]; }; // SAMPLES_PER_PATCH per link
layout(std430, binding = 3) readonly buffer DPoints { float d_points[]; };   // direct.comp's layout
layout(std430, binding = 4) readonly buffer Albedo { float albedo[]; };      // 3 n, channel-major
layout(std430, binding = 5) buffer C { float corr[]; };                       // 3 n, channel-major
layout(std430, binding = 6) readonly buffer B0 { float b0[]; };               // 3 n, channel-major
layout(std430, binding = 9) writeonly buffer BGather { float b_gather[]; };   // 3 n, channel-major
layout(std430, binding = 7) buffer Active { uint tile_active[]; };
layout(std430, binding = 8) buffer H { float h[]; };                          // 3 n, channel-major
layout(std430, binding = 10) readonly buffer Own { float own_w[]; };         // SAMPLES_PER_PATCH per patch
layout(std430, binding = 11) readonly buffer Receiver { float recv_w[]; };   // SAMPLES_PER_PATCH per link
layout(std430, binding = 12) writeonly buffer HPoints { float h_points[]; }; // 3 n SAMPLES_PER_PATCH, channel-major

uniform uint n;
uniform uint samples;
uniform uint stage;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= n) return;
    if (stage == 1u) {
        for (uint c = 0u; c < 3u; c++) h[c * n + i] += corr[c * n + i];
        return;
    }
    if (stage == 2u) {
        uint S = uint(SAMPLES_PER_PATCH);
        for (uint c = 0u; c < 3u; c++) {
            float d[SAMPLES_PER_PATCH];
            for (uint g = 0u; g < S; g++) d[g] = 0.0;
            for (uint l = starts[i]; l < starts[i + 1u]; l++) {
                uint p = link_patch[l];
                float b = b0[c * n + p] + albedo[c * n + p] * h[c * n + p];
                for (uint g = 0u; g < S; g++) d[g] += recv_w[l * S + g] * b;
            }
            for (uint g = 0u; g < S; g++) h_points[(c * n + i) * S + g] = d[g];
        }
        return;
    }
    vec3 cv = vec3(0.0);
    for (uint l = starts[i]; l < starts[i + 1u]; l++) {
        uint p = link_patch[l];
        for (uint c = 0u; c < 3u; c++) {
            float s = 0.0;
            for (uint g = 0u; g < samples; g++) {
                float b = albedo[c * n + p] * d_points[(c * n + p) * samples + g];
                s += link_w[l * uint(SAMPLES_PER_PATCH) + g] * b;
            }
            cv[c] += s;
        }
    }
    vec3 delta = vec3(0.0);
    for (uint c = 0u; c < 3u; c++) {
        for (uint g = 0u; g < samples; g++) {
            float b = albedo[c * n + i] * d_points[(c * n + i) * samples + g];
            delta[c] += own_w[i * uint(SAMPLES_PER_PATCH) + g] * b;
        }
    }
    bool any_light = false;
    for (uint c = 0u; c < 3u; c++) {
        corr[c * n + i] = cv[c];
        float b = b0[c * n + i] + delta[c] + albedo[c * n + i] * cv[c];
        b_gather[c * n + i] = b;
        any_light = any_light || b != 0.0;
    }
    if (any_light) tile_active[i / uint(TILE)] = 1u;
}

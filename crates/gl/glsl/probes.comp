// The probes' band-2 radiance coefficients from the patches' exitance
// (host: crates/gl/src/probes.rs; CPU reference:
// crates/runtime/src/probes.rs, Decoded::probe). One invocation per probe:
// the patch's reflected exitance B0_j - E_j + rho_j H_j for each patch
// entry, the sky's mean radiance for each sky entry, the material's
// emitted exitance (scale Ke) for each emission entry, times the entry's
// nine decoded weights.

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Starts { uint starts[]; };        // probes + 1
layout(std430, binding = 1) readonly buffer Patches { uint patches[]; };      // per entry
layout(std430, binding = 2) readonly buffer Weights { float weights[]; };     // 9 per entry
layout(std430, binding = 3) readonly buffer SkyStarts { uint sky_starts[]; }; // probes + 1
layout(std430, binding = 4) readonly buffer SkyCells { uint sky_cells[]; };   // per sky entry
layout(std430, binding = 5) readonly buffer SkyWeights { float sky_weights[]; };
layout(std430, binding = 6) readonly buffer B0 { float b0[]; };               // 3 n, channel-major
layout(std430, binding = 7) readonly buffer H { float h[]; };                 // 3 n, channel-major
layout(std430, binding = 8) readonly buffer Albedo { float albedo[]; };       // 3 n, channel-major
layout(std430, binding = 9) readonly buffer SkyRadiance { float sky_radiance[]; }; // 3 per cell
layout(std430, binding = 10) writeonly buffer Sh { float sh[]; };             // 27 per probe: 3 l + c
layout(std430, binding = 11) readonly buffer EmissionStarts { uint emission_starts[]; }; // probes + 1
layout(std430, binding = 12) readonly buffer Emitters { uint emitters[]; };   // per emission entry: material
layout(std430, binding = 13) readonly buffer EmissionWeights { float emission_weights[]; };
layout(std430, binding = 14) readonly buffer PatchEmission { float patch_e[]; }; // 3 n, channel-major
layout(std430, binding = 15) readonly buffer Emitted { float emitted[]; };     // 3 per material

uniform uint probe_count;
uniform uint n;
uniform bool has_sky;
uniform uint materials; // entries of Emitted

void main() {
    uint p = gl_GlobalInvocationID.x;
    if (p >= probe_count) return;
    float acc[27];
    for (int k = 0; k < 27; k++) acc[k] = 0.0;
    for (uint e = starts[p]; e < starts[p + 1u]; e++) {
        uint j = patches[e];
        vec3 b = vec3(b0[j] - patch_e[j] + albedo[j] * h[j],
                      b0[n + j] - patch_e[n + j] + albedo[n + j] * h[n + j],
                      b0[2u * n + j] - patch_e[2u * n + j] + albedo[2u * n + j] * h[2u * n + j]);
        for (uint l = 0u; l < 9u; l++) {
            float w = weights[9u * e + l];
            acc[3u * l] += w * b.x;
            acc[3u * l + 1u] += w * b.y;
            acc[3u * l + 2u] += w * b.z;
        }
    }
    if (has_sky) {
        for (uint e = sky_starts[p]; e < sky_starts[p + 1u]; e++) {
            uint c = sky_cells[e];
            vec3 b = vec3(sky_radiance[3u * c], sky_radiance[3u * c + 1u], sky_radiance[3u * c + 2u]);
            for (uint l = 0u; l < 9u; l++) {
                float w = sky_weights[9u * e + l];
                acc[3u * l] += w * b.x;
                acc[3u * l + 1u] += w * b.y;
                acc[3u * l + 2u] += w * b.z;
            }
        }
    }
    for (uint e = emission_starts[p]; e < emission_starts[p + 1u]; e++) {
        uint m = emitters[e];
        if (m >= materials) continue;
        vec3 b = vec3(emitted[3u * m], emitted[3u * m + 1u], emitted[3u * m + 2u]);
        for (uint l = 0u; l < 9u; l++) {
            float w = emission_weights[9u * e + l];
            acc[3u * l] += w * b.x;
            acc[3u * l + 1u] += w * b.y;
            acc[3u * l + 2u] += w * b.z;
        }
    }
    for (uint k = 0u; k < 27u; k++) sh[27u * p + k] = acc[k];
}

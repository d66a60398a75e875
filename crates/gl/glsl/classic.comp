// One pass of classic radiosity on the GPU (host: crates/gl/src/classic.rs; CPU
// reference: bench::frame::classic, tests/gl_classic.rs): y_c = F x_c for
// the three channels, reading F once, then H += y and the next pass's
// input x' = rho o y. k passes give k bounces; repeated until the error of
// the compressed gather is reached, they are the Jacobi iteration of the
// infinite-bounce limit (docs/design.md section 3's baseline).
//
// One group of 32 invocations per row of F (8 rows a work-group): the row
// is read as 16-byte words, consecutive invocations on consecutive words;
// x is staged in shared memory a chunk of CHUNK columns at a time; each
// invocation's sum is added in a fixed tree, so a pass is deterministic.

#define LANES 32
#define ROWS 8
#define CHUNK 1024

layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer F { vec4 f[]; };       // n rows of stride floats (zero-padded)
layout(std430, binding = 1) readonly buffer X { vec4 x[]; };       // stride columns: 3 channels and 0
layout(std430, binding = 2) writeonly buffer XNext { vec4 x_next[]; };
layout(std430, binding = 3) buffer H { vec4 h[]; };
layout(std430, binding = 4) readonly buffer Albedo { vec4 albedo[]; };

uniform uint n;
uniform uint stride; // floats a row of F, a multiple of 4

shared vec4 xs[CHUNK];
shared vec3 sums[256];

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint lane = lid % uint(LANES);
    uint row = gl_WorkGroupID.x * uint(ROWS) + lid / uint(LANES);
    uint words = stride / 4u;
    vec3 acc = vec3(0.0);
    for (uint c0 = 0u; c0 < stride; c0 += uint(CHUNK)) {
        for (uint k = lid; k < uint(CHUNK); k += 256u) {
            xs[k] = c0 + k < stride ? x[c0 + k] : vec4(0.0);
        }
        barrier();
        if (row < n) {
            uint w0 = c0 / 4u;
            uint w1 = min(words, w0 + uint(CHUNK) / 4u);
            for (uint w = w0 + lane; w < w1; w += uint(LANES)) {
                vec4 fv = f[row * words + w];
                uint q = 4u * (w - w0);
                acc += fv.x * xs[q].xyz + fv.y * xs[q + 1u].xyz + fv.z * xs[q + 2u].xyz
                    + fv.w * xs[q + 3u].xyz;
            }
        }
        barrier();
    }
    sums[lid] = acc;
    barrier();
    for (uint s = uint(LANES) / 2u; s > 0u; s >>= 1) {
        if (lane < s) sums[lid] += sums[lid + s];
        barrier();
    }
    if (lane == 0u && row < n) {
        vec3 y = sums[lid];
        h[row] = vec4(h[row].xyz + y, 0.0);
        x_next[row] = vec4(albedo[row].xyz * y, 0.0);
    }
}

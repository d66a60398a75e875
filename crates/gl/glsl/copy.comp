// A copy of one storage buffer into another (host: crates/gl/src/copy.rs; CPU
// reference: the identity, tests/gl_classic.rs): the memory roof the
// gather's effective bandwidth is measured against in the same run
// (`bench frame`), as STREAM's copy is on the CPU. Each invocation copies
// 16-byte words strided by the whole dispatch, so consecutive invocations
// touch consecutive words.

layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Src { uvec4 src[]; };
layout(std430, binding = 1) writeonly buffer Dst { uvec4 dst[]; };

uniform uint words; // 16-byte words to copy

void main() {
    uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    for (uint k = gl_GlobalInvocationID.x; k < words; k += stride) {
        dst[k] = src[k];
    }
}

// Shadow maps: the scene's front triangles seen from one shadow view
// (host: crates/gl/src/shadow.rs; the views: crates/gl/src/light.rs). Depth only.

layout(location = 0) in vec3 position;

uniform mat4 view_projection;

// The same position as the other pass's vertex shader computes, bit for
// bit: the shading pass's depth pre-pass (crates/gl/src/shade.rs) draws with
// shadow.vert, then shades with shade.vert at depth EQUAL.
invariant gl_Position;

void main() {
    gl_Position = view_projection * vec4(position, 1.0);
}

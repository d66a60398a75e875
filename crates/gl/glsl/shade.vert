// Shading: the scene's front triangles from the camera (host:
// crates/gl/src/shade.rs). Passes the world position, texture coordinates and
// triangle index to shade.frag.

layout(location = 0) in vec3 position;
layout(location = 1) in vec2 texcoord;
layout(location = 2) in uint triangle;

uniform mat4 view_projection;

// The same position as the other pass's vertex shader computes, bit for
// bit: the shading pass's depth pre-pass (crates/gl/src/shade.rs) draws with
// shadow.vert, then shades with shade.vert at depth EQUAL.
invariant gl_Position;

out vec3 v_position;
out vec2 v_texcoord;
flat out uint v_triangle;

void main() {
    v_position = position;
    v_texcoord = texcoord;
    v_triangle = triangle;
    gl_Position = view_projection * vec4(position, 1.0);
}

// Moving objects from the camera (host: crates/gl/src/objects.rs): world
// positions (the host places the meshes), normals and albedo per vertex.

layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec3 albedo;
layout(location = 3) in float probe; // the probe view's sphere's probe; -1: an object

uniform mat4 view_projection;

out vec3 v_position;
out vec3 v_normal;
out vec3 v_albedo;
flat out int v_probe;

void main() {
    v_position = position;
    v_normal = normal;
    v_albedo = albedo;
    v_probe = int(probe);
    gl_Position = view_projection * vec4(position, 1.0);
}

// Shadow maps: depth only (crates/gl/src/shadow.rs). Both sides of a triangle
// cast, as the CPU's shadow rays are blocked by either side.

void main() {
}

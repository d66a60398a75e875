// Voxelization: which voxels each triangle overlaps, and the piece of the
// triangle inside each of them (its area and centroid).
//
// Coordinates are grid coordinates (world position minus the grid origin,
// divided by the voxel size), so voxel (i, j, k) is the box [i, i+1] x
// [j, j+1] x [k, k+1] and every voxel boundary is an integer, exactly
// representable in f32. The host reduces the pieces into patches; this file
// only measures. The CPU reference is `voxelize::cpu_pieces` in
// crates/bake/src/voxelize/mod.rs, which follows this code step by step in f64.
//
// Two kernels share one walk over candidate voxels: `count_pieces` counts
// the voxels each triangle overlaps, the host turns the counts into offsets
// (exclusive prefix sum), and `emit_pieces` writes the pieces there. The
// output order (triangle, then walk order) is deterministic.

// Half size of the box used by the overlap test: a little more than 0.5 so
// that the test stays conservative under f32 rounding of the inputs (grid
// coordinates up to ~4096 carry absolute errors of ~2.5e-4 voxels). Clipping
// decides the actual area. Must equal `SAT_HALF` in crates/bake/src/voxelize/mod.rs.
#define SAT_HALF 0.5005f

// The clipped polygon has at most 3 + 6 vertices.
#define MAX_POLY 10

typedef struct {
    uint tri;
    uint vx, vy, vz;
    float area;   // area of the piece, in voxel-face units
    float cx, cy, cz; // centroid of the piece, relative to the voxel corner
} Piece;

static float max3(float a, float b, float c) { return fmax(a, fmax(b, c)); }
static float min3(float a, float b, float c) { return fmin(a, fmin(b, c)); }

// Separating-axis test of a triangle against the box [-h, h]^3
// (Akenine-Moeller, "Fast 3D Triangle-Box Overlap Testing", 2001): the
// three box normals, the triangle normal, and the nine edge-axis cross
// products. Touching counts as overlapping (conservative).
static int tri_box_overlap(const float a[3], const float b[3], const float c[3], float h)
{
    for (int k = 0; k < 3; ++k) {
        if (min3(a[k], b[k], c[k]) > h || max3(a[k], b[k], c[k]) < -h) return 0;
    }
    float e[3][3];
    for (int k = 0; k < 3; ++k) {
        e[0][k] = b[k] - a[k];
        e[1][k] = c[k] - b[k];
        e[2][k] = a[k] - c[k];
    }
    float n[3] = {
        e[0][1] * e[1][2] - e[0][2] * e[1][1],
        e[0][2] * e[1][0] - e[0][0] * e[1][2],
        e[0][0] * e[1][1] - e[0][1] * e[1][0],
    };
    float d = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
    float r = h * (fabs(n[0]) + fabs(n[1]) + fabs(n[2]));
    if (fabs(d) > r) return 0;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            // axis = e_i x unit_j
            float ax[3] = {0.0f, 0.0f, 0.0f};
            int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            ax[j1] = e[i][j2];
            ax[j2] = -e[i][j1];
            float pa = ax[0] * a[0] + ax[1] * a[1] + ax[2] * a[2];
            float pb = ax[0] * b[0] + ax[1] * b[1] + ax[2] * b[2];
            float pc = ax[0] * c[0] + ax[1] * c[1] + ax[2] * c[2];
            float rr = h * (fabs(ax[0]) + fabs(ax[1]) + fabs(ax[2]));
            if (min3(pa, pb, pc) > rr || max3(pa, pb, pc) < -rr) return 0;
        }
    }
    return 1;
}

// Sutherland-Hodgman clip of a polygon against x_k >= 0 (keep_high == 0) or
// x_k <= 1 (keep_high == 1). Points on the plane are inside, and new points
// get the plane's coordinate exactly, so pieces that lie in a voxel face keep
// exact face coordinates.
static int clip_axis(float src[MAX_POLY][3], int m, float dst[MAX_POLY][3], int k, int keep_high)
{
    int out = 0;
    for (int i = 0; i < m; ++i) {
        int p = (i + m - 1) % m;
        float dc = keep_high ? 1.0f - src[i][k] : src[i][k];
        float dp = keep_high ? 1.0f - src[p][k] : src[p][k];
        int cin = dc >= 0.0f, pin = dp >= 0.0f;
        if (cin != pin && out < MAX_POLY) {
            float t = dp / (dp - dc);
            for (int q = 0; q < 3; ++q) dst[out][q] = src[p][q] + t * (src[i][q] - src[p][q]);
            dst[out][k] = keep_high ? 1.0f : 0.0f;
            ++out;
        }
        if (cin && out < MAX_POLY) {
            for (int q = 0; q < 3; ++q) dst[out][q] = src[i][q];
            ++out;
        }
    }
    return out;
}

// Area and centroid of the part of triangle (a, b, c) inside the unit box,
// all coordinates relative to the voxel corner. A piece lying flat in a face
// of the box belongs to the voxel its normal points into: it is dropped here
// (area 0) when the normal points out of this voxel through that face, so a
// surface exactly on a voxel boundary is counted once.
static float clip_piece(const float a[3], const float b[3], const float c[3], const float n[3],
                        float centroid[3])
{
    float pa[MAX_POLY][3], pb[MAX_POLY][3];
    for (int q = 0; q < 3; ++q) { pa[0][q] = a[q]; pa[1][q] = b[q]; pa[2][q] = c[q]; }
    int m = 3;
    for (int k = 0; k < 3 && m > 0; ++k) {
        m = clip_axis(pa, m, pb, k, 0);
        m = clip_axis(pb, m, pa, k, 1);
    }
    centroid[0] = centroid[1] = centroid[2] = 0.0f;
    if (m < 3) return 0.0f;
    for (int k = 0; k < 3; ++k) {
        int all_lo = 1, all_hi = 1;
        for (int i = 0; i < m; ++i) {
            all_lo &= pa[i][k] == 0.0f;
            all_hi &= pa[i][k] == 1.0f;
        }
        if ((all_lo && n[k] < 0.0f) || (all_hi && n[k] > 0.0f)) return 0.0f;
    }
    // Fan triangulation from vertex 0; signed areas along the unit normal.
    float nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    float area2 = 0.0f, acc[3] = {0.0f, 0.0f, 0.0f};
    for (int i = 1; i + 1 < m; ++i) {
        float u[3], v[3];
        for (int q = 0; q < 3; ++q) { u[q] = pa[i][q] - pa[0][q]; v[q] = pa[i + 1][q] - pa[0][q]; }
        float cr[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        float s = (cr[0] * n[0] + cr[1] * n[1] + cr[2] * n[2]) / nl;
        area2 += s;
        for (int q = 0; q < 3; ++q) acc[q] += s * (pa[0][q] + pa[i][q] + pa[i + 1][q]);
    }
    if (!(area2 > 0.0f)) return 0.0f;
    for (int q = 0; q < 3; ++q) centroid[q] = acc[q] / (3.0f * area2);
    return 0.5f * area2;
}

// Walks the candidate voxels of triangle t: for every cell of the triangle's
// bounding box in the two axes other than the dominant normal axis w, the
// voxels in w that the triangle's plane crosses in that cell (plus one on
// each side against rounding), each tested with the overlap test. Counts
// overlapping voxels; writes pieces when `out` is given.
static uint walk(global const float* tri_coords, uint t, uint dx, uint dy, uint dz,
                 global Piece* out)
{
    float v[3][3];
    for (int i = 0; i < 3; ++i)
        for (int q = 0; q < 3; ++q) v[i][q] = tri_coords[9 * t + 3 * i + q];
    float e1[3], e2[3];
    for (int q = 0; q < 3; ++q) { e1[q] = v[1][q] - v[0][q]; e2[q] = v[2][q] - v[0][q]; }
    float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                  e1[0] * e2[1] - e1[1] * e2[0]};
    float an[3] = {fabs(n[0]), fabs(n[1]), fabs(n[2])};
    int w = (an[0] >= an[1] && an[0] >= an[2]) ? 0 : (an[1] >= an[2] ? 1 : 2);
    int u = (w + 1) % 3, x = (w + 2) % 3;
    int dims[3] = {(int)dx, (int)dy, (int)dz};
    int lo[3], hi[3];
    for (int q = 0; q < 3; ++q) {
        lo[q] = clamp((int)floor(min3(v[0][q], v[1][q], v[2][q]) - (SAT_HALF - 0.5f)), 0, dims[q] - 1);
        hi[q] = clamp((int)floor(max3(v[0][q], v[1][q], v[2][q]) + (SAT_HALF - 0.5f)), 0, dims[q] - 1);
    }
    uint count = 0;
    for (int iu = lo[u]; iu <= hi[u]; ++iu) {
        for (int ix = lo[x]; ix <= hi[x]; ++ix) {
            int w0 = lo[w], w1 = hi[w];
            if (an[w] > 0.0f) {
                // The plane's w over the cell's four corners (linear in u, x).
                float wmin = INFINITY, wmax = -INFINITY;
                for (int cu = 0; cu < 2; ++cu) {
                    for (int cx = 0; cx < 2; ++cx) {
                        float pu = (float)(iu + cu), px = (float)(ix + cx);
                        float pw = v[0][w] - (n[u] * (pu - v[0][u]) + n[x] * (px - v[0][x])) / n[w];
                        wmin = fmin(wmin, pw);
                        wmax = fmax(wmax, pw);
                    }
                }
                w0 = max(w0, (int)floor(wmin) - 1);
                w1 = min(w1, (int)floor(wmax) + 1);
            }
            for (int iw = w0; iw <= w1; ++iw) {
                int cell[3];
                cell[u] = iu; cell[x] = ix; cell[w] = iw;
                float a[3], b[3], c[3];
                for (int q = 0; q < 3; ++q) {
                    float centre = (float)cell[q] + 0.5f;
                    a[q] = v[0][q] - centre; b[q] = v[1][q] - centre; c[q] = v[2][q] - centre;
                }
                if (!tri_box_overlap(a, b, c, SAT_HALF)) continue;
                if (out) {
                    float la[3], lb[3], lc[3], centroid[3];
                    for (int q = 0; q < 3; ++q) {
                        la[q] = v[0][q] - (float)cell[q];
                        lb[q] = v[1][q] - (float)cell[q];
                        lc[q] = v[2][q] - (float)cell[q];
                    }
                    float area = clip_piece(la, lb, lc, n, centroid);
                    global Piece* p = out + count;
                    p->tri = t;
                    p->vx = (uint)cell[0]; p->vy = (uint)cell[1]; p->vz = (uint)cell[2];
                    p->area = area;
                    p->cx = centroid[0]; p->cy = centroid[1]; p->cz = centroid[2];
                }
                ++count;
            }
        }
    }
    return count;
}

kernel void count_pieces(global const float* tri_coords, uint n_tris, uint dx, uint dy, uint dz,
                         global uint* counts)
{
    uint t = get_global_id(0);
    if (t >= n_tris) return;
    counts[t] = walk(tri_coords, t, dx, dy, dz, 0);
}

// Pieces of triangles first_tri .. last_tri - 1 (one batch, sized by the
// host to fit the device's allocation limit), written at offsets relative to
// the batch's first piece.
kernel void emit_pieces(global const float* tri_coords, uint first_tri, uint last_tri, uint dx,
                        uint dy, uint dz, global const ulong* offsets, global Piece* pieces)
{
    uint t = first_tri + get_global_id(0);
    if (t >= last_tri) return;
    walk(tri_coords, t, dx, dy, dz, pieces + offsets[t - first_tri]);
}

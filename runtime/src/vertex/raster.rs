//! A software rasterizer that sees exactly what the reference tracer's primary rays see: for
//! each pixel, the triangle met first along the ray through the pixel's centre, that ray's
//! perspective-correct barycentrics and its distance (docs/conventions.md, "Camera").
//!
//! **Edge functions through the eye.** In camera coordinates (the eye at the origin, a pixel's
//! ray along `d = (sx, sy, 1)`), the plane through the eye and a triangle's edge `(Vj, Vk)` has
//! the normal `ni = Vj x Vk`, and `wi = ni . d` is linear in the film position `(sx, sy)`. The
//! ray meets the triangle in front of the eye exactly when the three `wi` share the sign of
//! `det = V0 . (V1 x V2)`, and `wi / (w0 + w1 + w2)` is then the weight of vertex `i` at the hit:
//! the perspective-correct barycentrics, with no division by a vertex's depth, so a triangle
//! crossing the camera plane needs no special case to be drawn right. This is the same sign
//! test a ray-triangle intersection makes, which is why the rasterizer and the tracer agree
//! pixel for pixel.
//!
//! **Shared edges.** The two triangles on either side of an edge compute its `ni` from the same
//! two vertices, so their edge values are exact negatives at every pixel (each pixel's value is
//! evaluated from the same tables, never accumulated): a pixel centre strictly inside one is
//! strictly outside the other. A centre exactly on the edge (`wi == 0`) goes to the triangle
//! for which `ni` is lexicographically positive, i.e. as if the ray were nudged by
//! `(e, e^2, e^3)`; the neighbour's `-ni` is then negative, so no pixel is covered twice or
//! missed (the exact equivalent of a top-left rule).
//!
//! **Near plane.** Nothing nearer than [`NEAR_PLANE_RELATIVE`] times the farthest vertex's
//! distance (along the view axis) is drawn. The edge test alone is already right for a
//! triangle running under the camera; the near plane bounds the image rectangle such a
//! triangle is searched in (its part in front of the plane, projected), and the per-pixel depth
//! test `z >= near` makes the drawn part exactly that clipped triangle.
//!
//! **Work.** Vertices are moved into camera space once. Each triangle is culled when it lies
//! entirely outside one side of the view, and otherwise binned, with its pixel rectangle, into
//! the bands of [`BAND_ROWS`] image rows it overlaps. Bands are rasterized in parallel, each
//! into its own z-buffer of inverse depth `1 / z` (linear in `(sx, sy)`), computing the edge
//! functions of its triangles as it meets them, in triangle order; an equal depth does not
//! replace, so of equally near triangles the lowest index is seen, on any thread count.

use prt_formats::view::CameraFrame;
use rayon::prelude::*;

use super::view::{check_indices, cross, dot, RasterError, ViewRays, NO_TRIANGLE};

/// The near plane, as a fraction of the farthest vertex's camera-space distance (the largest
/// `|x|`, `|y|` or `|z|` over all finite vertices). The reference tracer has no near plane; at
/// 1e-5 of the scene's depth, only a surface touching the eye (where no image is meaningful)
/// is left out, while the near plane stays far enough from the eye for projections to be
/// well conditioned.
pub(crate) const NEAR_PLANE_RELATIVE: f64 = 1e-5;

/// Image rows per band, the unit of parallel work and binning.
pub(crate) const BAND_ROWS: u32 = 16;

/// Triangles per binning task.
const CHUNK: usize = 4096;

/// How far (in pixels) a triangle's projected rectangle is widened before rounding to pixel
/// centres: far more than the rounding between the projection and the edge functions (about
/// 1e-12 pixel), so a covered centre is never left outside its triangle's rectangle.
const RECT_PAD: f64 = 1e-3;

/// What one pixel sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fragment {
    /// Index of the triangle seen, or [`NO_TRIANGLE`].
    pub(crate) triangle: u32,
    /// The weights of the triangle's vertices 1 and 2 at the point seen (vertex 0's weight is
    /// `1 - bary[0] - bary[1]`), as the tracer's hit reports them: perspective-correct, the
    /// point where the pixel centre's ray meets the triangle. Zero when nothing is seen.
    pub(crate) bary: [f32; 2],
    /// Distance from the eye to that point along the unit view direction (world units);
    /// infinite when nothing is seen.
    pub(crate) distance: f32,
}

impl Fragment {
    /// A pixel that sees nothing.
    pub(crate) const EMPTY: Fragment = Fragment {
        triangle: NO_TRIANGLE,
        bary: [0.0; 2],
        distance: f32::INFINITY,
    };

    /// True when the pixel sees no triangle.
    pub(crate) fn is_empty(&self) -> bool {
        self.triangle == NO_TRIANGLE
    }
}

/// The rasterizer's output: one [`Fragment`] per pixel.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct VisibilityBuffer {
    /// Image width in pixels.
    pub(crate) width: u32,
    /// Image height in pixels.
    pub(crate) height: u32,
    /// The near-plane distance used (camera-space depth, world units).
    pub(crate) near: f64,
    /// Row-major, top row first (`width * height` fragments).
    pub(crate) fragments: Vec<Fragment>,
}

/// Renders the visibility buffer of a triangle mesh seen by `camera` at `width` x `height`:
/// for each pixel centre, the nearest triangle its ray meets (either side: triangles are
/// two-sided), the perspective-correct barycentrics there and the distance.
///
/// Degenerate (zero-area, or seen exactly edge-on) triangles and triangles with a non-finite
/// vertex are skipped; nothing nearer than the near plane ([`NEAR_PLANE_RELATIVE`]) is drawn.
/// Runs on the current rayon pool; the result is the same on any number of threads. To render
/// many frames, keep a [`Rasterizer`], which reuses its memory.
#[cfg(test)]
pub(crate) fn rasterize(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    camera: &CameraFrame,
    width: u32,
    height: u32,
) -> Result<VisibilityBuffer, RasterError> {
    let mut out = VisibilityBuffer {
        width: 0,
        height: 0,
        near: 0.0,
        fragments: Vec::new(),
    };
    Rasterizer::new().render(positions, triangles, camera, width, height, &mut out)?;
    Ok(out)
}

/// The working memory of [`rasterize`], kept between frames so that rendering one allocates
/// nothing once the sizes have settled.
#[derive(Default)]
pub(crate) struct Rasterizer {
    verts: Vec<Vertex>,
    chunks: Vec<ChunkBins>,
    bands: Vec<BandScratch>,
    sx: Vec<f64>,
    sy: Vec<f64>,
}

impl Rasterizer {
    /// A rasterizer with no memory reserved yet.
    pub(crate) fn new() -> Rasterizer {
        Rasterizer::default()
    }

    /// [`rasterize`] into `out`, whose previous contents are replaced (its memory is reused).
    /// On error `out` is left as it was.
    pub(crate) fn render(
        &mut self,
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
        camera: &CameraFrame,
        width: u32,
        height: u32,
        out: &mut VisibilityBuffer,
    ) -> Result<(), RasterError> {
        let rays = ViewRays::new(camera, width, height)?;
        check_indices(positions.len(), triangles)?;

        // Camera space, then the near plane from the farthest finite vertex (max is exact in
        // any order), then outcodes and projections.
        let space = CameraSpace::new(&rays);
        self.verts.clear();
        positions
            .par_iter()
            .with_min_len(4096)
            .map(|p| Vertex {
                c: space.to_camera(*p),
                px: 0.0,
                py: 0.0,
                out: 0,
            })
            .collect_into_vec(&mut self.verts);
        let extent = self
            .verts
            .par_iter()
            .with_min_len(4096)
            .map(|v| v.c)
            .filter(|c| c.iter().all(|v| v.is_finite()))
            .map(|c| c[0].abs().max(c[1].abs()).max(c[2].abs()))
            .reduce(|| 0.0, f64::max);
        let near = (NEAR_PLANE_RELATIVE * extent).max(f64::MIN_POSITIVE);
        let film = Film::new(&rays, near);
        self.verts
            .par_iter_mut()
            .with_min_len(4096)
            .for_each(|v| film.place(v));

        let bands = height.div_ceil(BAND_ROWS) as usize;
        let verts = &self.verts;
        self.chunks
            .resize_with(triangles.len().div_ceil(CHUNK), ChunkBins::default);
        self.chunks
            .par_iter_mut()
            .zip(triangles.par_chunks(CHUNK))
            .enumerate()
            .for_each(|(c, (bins, tris))| bins.fill(&film, verts, tris, c * CHUNK, bands));

        self.sx.clear();
        self.sx
            .extend((0..width).map(|x| rays.film(f64::from(x) + 0.5, 0.0).0));
        self.sy.clear();
        self.sy
            .extend((0..height).map(|y| rays.film(0.0, f64::from(y) + 0.5).1));
        let tables = Tables {
            rays: &rays,
            triangles,
            verts: &self.verts,
            film: &film,
            sx: &self.sx,
            sy: &self.sy,
            q_near: 1.0 / near,
        };
        let pixels = width as usize * height as usize;
        out.fragments.clear();
        out.fragments.resize(pixels, Fragment::EMPTY);
        self.bands.resize_with(bands, BandScratch::default);
        let chunks = &self.chunks;
        out.fragments
            .par_chunks_mut(width as usize * BAND_ROWS as usize)
            .zip(self.bands.par_iter_mut())
            .enumerate()
            .for_each(|(band, (frags, scratch))| {
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2 (checked just above).
                    unsafe { raster_band_avx2(&tables, chunks, band, scratch, frags) };
                    return;
                }
                raster_band(&tables, chunks, band, scratch, frags)
            });
        out.width = width;
        out.height = height;
        out.near = near;
        Ok(())
    }
}

/// World to camera coordinates: `p - eye = x right + y up + z forward`, solved with the
/// inverse of the frame's matrix, so the film formula's rays (built from the same three
/// vectors) are exactly `(sx, sy, 1)` here even if the frame is not perfectly orthonormal.
struct CameraSpace {
    eye: [f64; 3],
    /// Rows of the inverse of the matrix with columns right, up, forward.
    inverse: [[f64; 3]; 3],
}

impl CameraSpace {
    fn new(rays: &ViewRays) -> CameraSpace {
        let (r, u, f) = (rays.right, rays.up, rays.forward);
        let det = dot(r, cross(u, f));
        // Rows of the inverse are the cross products of the other two columns over det.
        let inverse = [cross(u, f), cross(f, r), cross(r, u)].map(|row| row.map(|c| c / det));
        CameraSpace {
            eye: rays.position,
            inverse,
        }
    }

    #[inline]
    fn to_camera(&self, p: [f32; 3]) -> [f64; 3] {
        let d = std::array::from_fn(|i| f64::from(p[i]) - self.eye[i]);
        self.inverse.map(|row| dot(row, d))
    }
}

// Outcode bits of a camera-space vertex: outside which side of the view it lies.
const OUT_NEAR: u8 = 1;
const OUT_LEFT: u8 = 2;
const OUT_RIGHT: u8 = 4;
const OUT_BOTTOM: u8 = 8;
const OUT_TOP: u8 = 16;
const OUT_NONFINITE: u8 = 32;

/// A vertex in camera space, with where it projects (pixels) when in front of the near plane.
#[derive(Clone, Copy)]
struct Vertex {
    c: [f64; 3],
    px: f64,
    py: f64,
    out: u8,
}

/// The film's extent in camera space and its mapping to pixel coordinates.
struct Film {
    near: f64,
    /// Film half-extents: the image spans `|sx| <= half_x`, `|sy| <= half_y`.
    half_x: f64,
    half_y: f64,
    width: f64,
    height: f64,
}

impl Film {
    fn new(rays: &ViewRays, near: f64) -> Film {
        Film {
            near,
            half_x: rays.tan_half_fov * rays.aspect,
            half_y: rays.tan_half_fov,
            width: f64::from(rays.width),
            height: f64::from(rays.height),
        }
    }

    /// Pixel coordinates (film position, y down) of film offsets: the inverse of
    /// [`ViewRays::film`].
    #[inline]
    fn pixel(&self, sx: f64, sy: f64) -> (f64, f64) {
        (
            (sx / self.half_x + 1.0) * 0.5 * self.width,
            (1.0 - sy / self.half_y) * 0.5 * self.height,
        )
    }

    /// Sets a camera-space vertex's outcode and, when in front of the near plane, where it
    /// projects.
    fn place(&self, v: &mut Vertex) {
        let [x, y, z] = v.c;
        if !v.c.iter().all(|c| c.is_finite()) {
            v.out = OUT_NONFINITE;
            return;
        }
        // The four side planes pass through the eye, so these tests hold behind it too.
        let mut out = 0;
        if z < self.near {
            out |= OUT_NEAR;
        }
        if x < -z * self.half_x {
            out |= OUT_LEFT;
        }
        if x > z * self.half_x {
            out |= OUT_RIGHT;
        }
        if y < -z * self.half_y {
            out |= OUT_BOTTOM;
        }
        if y > z * self.half_y {
            out |= OUT_TOP;
        }
        if out & OUT_NEAR == 0 {
            (v.px, v.py) = self.pixel(x / z, y / z);
        }
        v.out = out;
    }
}

/// A triangle binned for rasterizing: its index, the inclusive rectangle of pixel centres it
/// may cover (empty, `x0 > x1`, when it covers none) and the inclusive rectangle of pixels
/// whose area its projection may overlap (what the multi-sample pass, `samples.rs`, reads;
/// it is binned by the latter's rows).
#[derive(Clone, Copy, Default)]
struct Entry {
    triangle: u32,
    x0: u16,
    x1: u16,
    y0: u16,
    y1: u16,
    area: Area,
}

/// An inclusive rectangle of pixels.
#[derive(Clone, Copy, Default)]
struct Area {
    x0: u16,
    x1: u16,
    y0: u16,
    y1: u16,
}

impl Entry {
    /// Whether the triangle may cover a pixel centre.
    fn covers_centres(&self) -> bool {
        self.x0 <= self.x1
    }
}

/// A triangle's edge functions, computed where it is rasterized (per band, from the
/// camera-space vertices: cheaper than storing and fetching them for the whole frame).
#[derive(Clone, Copy)]
pub(crate) struct Edges {
    /// Edge-plane normals, oriented so the inside is where all three `n . (sx, sy, 1)` are
    /// positive. Their sum dotted with `(sx, sy, 1)` is `|det| / z`.
    n: [[f64; 3]; 3],
    /// `1 / |det|`: the inverse depth is the sum of the edge values times this.
    inv_det: f64,
    triangle: u32,
    /// Which edges own the pixel centres lying exactly on them (bit i for edge i).
    owns: u8,
}

/// A chunk's visible triangles, sorted by band (a counting sort; a triangle over several
/// bands is in each), so that a band reads its triangles as contiguous runs.
#[derive(Default)]
struct ChunkBins {
    /// The chunk's entries in triangle order (working memory of the sort).
    unsorted: Vec<Entry>,
    /// `entries[starts[b]..starts[b + 1]]` overlap band `b`, in triangle order.
    entries: Vec<Entry>,
    starts: Vec<u32>,
    /// Where each band's next entry goes while sorting.
    cursor: Vec<u32>,
}

/// Whether an edge owns pixel centres exactly on it: its normal is lexicographically
/// positive, i.e. the ray nudged by (e, e^2, e^3) is on its inside.
fn owns_ties(n: [f64; 3]) -> bool {
    if n[0] != 0.0 {
        n[0] > 0.0
    } else if n[1] != 0.0 {
        n[1] > 0.0
    } else {
        n[2] > 0.0
    }
}

impl ChunkBins {
    /// Culls and bins by band the chunk of triangles starting at index `first`.
    fn fill(
        &mut self,
        film: &Film,
        verts: &[Vertex],
        tris: &[[u32; 3]],
        first: usize,
        bands: usize,
    ) {
        self.unsorted.clear();
        self.unsorted.extend(
            tris.iter()
                .enumerate()
                .filter_map(|(i, tri)| entry(film, tri.map(|v| verts[v as usize]), first + i)),
        );
        let band_of = |y: u16| usize::from(y) / BAND_ROWS as usize;
        self.starts.clear();
        self.starts.resize(bands + 1, 0);
        for e in &self.unsorted {
            for b in band_of(e.area.y0)..=band_of(e.area.y1) {
                self.starts[b + 1] += 1;
            }
        }
        for b in 0..bands {
            self.starts[b + 1] += self.starts[b];
        }
        // Every slot is written below, so stale entries from the last frame may stay in place
        // of a fill (only a longer list writes its new tail).
        self.entries
            .resize(self.starts[bands] as usize, Entry::default());
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.starts[..bands]);
        for e in &self.unsorted {
            for b in band_of(e.area.y0)..=band_of(e.area.y1) {
                self.entries[self.cursor[b] as usize] = *e;
                self.cursor[b] += 1;
            }
        }
    }
}

/// A triangle's bin entry, or `None` when it cannot be seen: culled against one side of the
/// view, non-finite, or overlapping no pixel.
fn entry(film: &Film, v: [Vertex; 3], triangle: usize) -> Option<Entry> {
    let (all, any) = (
        v[0].out & v[1].out & v[2].out,
        v[0].out | v[1].out | v[2].out,
    );
    if all != 0 || any & OUT_NONFINITE != 0 {
        return None;
    }
    let (area, centres) = rectangle(film, &v)?;
    let ((x0, y0), (x1, y1)) = centres.unwrap_or(((1, 0), (0, 0)));
    Some(Entry {
        triangle: triangle as u32,
        x0,
        x1,
        y0,
        y1,
        area,
    })
}

/// A triangle's edge functions from its camera-space vertices, or `None` when it is
/// degenerate: zero area, or the eye in its plane (seen edge-on), which the tracer's
/// intersection test refuses too.
fn edges(c: [[f64; 3]; 3], triangle: u32) -> Option<Edges> {
    let mut n = [cross(c[1], c[2]), cross(c[2], c[0]), cross(c[0], c[1])];
    let det = dot(c[0], n[0]);
    if !det.is_finite() || det == 0.0 || n.contains(&[0.0; 3]) {
        return None;
    }
    if det < 0.0 {
        n = n.map(|e| e.map(|x| -x));
    }
    let inv_det = 1.0 / det.abs();
    if !inv_det.is_finite() {
        return None;
    }
    let owns = (0..3).fold(0u8, |m, i| m | (u8::from(owns_ties(n[i])) << i));
    Some(Edges {
        n,
        inv_det,
        triangle,
        owns,
    })
}

/// The inclusive range of pixels (x, y) whose area the triangle's part in front of the near
/// plane projects onto, clamped to the image (`None` when it is empty), and of the pixel
/// centres in it (`None` when there is none).
#[allow(clippy::type_complexity)]
fn rectangle(film: &Film, v: &[Vertex; 3]) -> Option<(Area, Option<((u16, u16), (u16, u16))>)> {
    let mut min = (f64::INFINITY, f64::INFINITY);
    let mut max = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut add = |(px, py): (f64, f64)| {
        min = (min.0.min(px), min.1.min(py));
        max = (max.0.max(px), max.1.max(py));
    };
    if v.iter().all(|v| v.out & OUT_NEAR == 0) {
        v.iter().for_each(|v| add((v.px, v.py)));
    } else {
        // Clip against z = near: keep the vertices in front, add where edges cross the plane.
        for i in 0..3 {
            let (a, b) = (&v[i], &v[(i + 1) % 3]);
            if a.out & OUT_NEAR == 0 {
                add((a.px, a.py));
            }
            if (a.out ^ b.out) & OUT_NEAR != 0 {
                let t = (film.near - a.c[2]) / (b.c[2] - a.c[2]);
                let x = a.c[0] + (b.c[0] - a.c[0]) * t;
                let y = a.c[1] + (b.c[1] - a.c[1]) * t;
                add(film.pixel(x / film.near, y / film.near));
            }
        }
    }
    // Pixel centres are at index + 0.5.
    let range = |lo: f64, hi: f64, size: f64| -> Option<(u16, u16)> {
        let first = (-floor_within(-(lo - 0.5 - RECT_PAD), size)).max(0.0);
        let last = floor_within(hi - 0.5 + RECT_PAD, size).min(size - 1.0);
        // `as u16` of the clamped values is exact (size <= MAX_IMAGE_SIDE).
        (first <= last).then_some((first as u16, last as u16))
    };
    // Pixel i spans [i, i + 1).
    let area = |lo: f64, hi: f64, size: f64| -> Option<(u16, u16)> {
        let first = floor_within(lo - RECT_PAD, size).max(0.0);
        let last = floor_within(hi + RECT_PAD, size).min(size - 1.0);
        (first <= last).then_some((first as u16, last as u16))
    };
    let (ax0, ax1) = area(min.0, max.0, film.width)?;
    let (ay0, ay1) = area(min.1, max.1, film.height)?;
    let area = Area {
        x0: ax0,
        x1: ax1,
        y0: ay0,
        y1: ay1,
    };
    let centres = range(min.0, max.0, film.width)
        .zip(range(min.1, max.1, film.height))
        .map(|((x0, x1), (y0, y1))| ((x0, y0), (x1, y1)));
    Some((area, centres))
}

/// `x.floor()` where only values in [-size, size] matter: others are clamped to just beyond
/// (so `-floor_within(-x)` is a ceiling with the same property; NaN becomes 0). The baseline
/// x86-64 target has no rounding instruction and `floor` is a library call there, which
/// triangle setup would pay four times.
#[inline]
fn floor_within(x: f64, size: f64) -> f64 {
    let x = x.clamp(-size - 2.0, size + 2.0);
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// Per-frame tables shared by all bands.
struct Tables<'a> {
    rays: &'a ViewRays,
    triangles: &'a [[u32; 3]],
    verts: &'a [Vertex],
    film: &'a Film,
    /// Film offsets of the pixel centres of each column and row.
    sx: &'a [f64],
    sy: &'a [f64],
    /// Inverse depth of the near plane.
    q_near: f64,
}

/// A band's working memory: the edge functions of its triangles, in the order met (chunk by
/// chunk, each in triangle order, so positions grow with the triangle index), and its
/// z-buffer: per pixel, the nearest inverse depth so far and the position of its triangle.
#[derive(Default)]
struct BandScratch {
    edges: Vec<Edges>,
    depth: Vec<f64>,
    seq: Vec<u32>,
}

/// The smaller of two values (no NaN handling: the compiler's plain `minsd`).
#[inline(always)]
fn min(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// Whether a pixel is inside an edge: strictly, or on it if the edge owns it.
#[inline(always)]
fn inside(w: f64, owns: bool) -> bool {
    (w > 0.0) | ((w == 0.0) & owns)
}

/// Rectangles at least this wide search each row for the span inside the triangle first.
const SPAN_MIN_WIDTH: usize = 8;

/// Columns `x0..=x1` of a row that can be inside all three edges whose row values (at `sy`)
/// are `r`: each edge bounds `sx` on one side, which is turned into a column one pixel wider
/// than it (the per-pixel test decides exactly). `None` when no column can be.
#[inline]
fn row_span(
    t: &Tables,
    n: &[[f64; 3]; 3],
    r: [f64; 3],
    x0: usize,
    x1: usize,
) -> Option<(usize, usize)> {
    let (mut lo, mut hi) = (x0 as f64, x1 as f64);
    for (e, r) in n.iter().zip(r) {
        if e[0] == 0.0 {
            if r < 0.0 {
                return None;
            }
            continue;
        }
        // The column whose centre is at the edge's zero: sx = -r / nx.
        let (col, _) = t.film.pixel(-r / e[0], 0.0);
        let col = col - 0.5;
        if e[0] > 0.0 {
            lo = lo.max(floor_within(col, t.film.width) - 1.0);
        } else {
            hi = hi.min(-floor_within(-col, t.film.width) + 1.0);
        }
    }
    // NaN (a degenerate bound) leaves the whole rectangle to the per-pixel test.
    let (lo, hi) = (lo.max(x0 as f64), hi.min(x1 as f64));
    if lo > hi {
        return None;
    }
    Some((lo as usize, hi as usize))
}

/// [`raster_band`] compiled for AVX2: its branch-free pixel loop runs four f64 lanes instead
/// of two. The same operations in the same order (Rust never fuses a multiply and an add), so
/// the same fragments bit for bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn raster_band_avx2(
    t: &Tables,
    chunks: &[ChunkBins],
    band: usize,
    z: &mut BandScratch,
    out: &mut [Fragment],
) {
    raster_band(t, chunks, band, z, out)
}

/// Rasterizes band `band` (its rows of `out`) and resolves each pixel's fragment.
#[inline(always)]
fn raster_band(
    t: &Tables,
    chunks: &[ChunkBins],
    band: usize,
    z: &mut BandScratch,
    out: &mut [Fragment],
) {
    const NONE: u32 = u32::MAX;
    let width = t.film.width as usize;
    let pitch = t.sx.len();
    let y_first = band * BAND_ROWS as usize;
    let rows = out.len() / width;
    z.depth.clear();
    z.depth.resize(rows * pitch, 0.0);
    z.seq.clear();
    z.seq.resize(rows * pitch, NONE);
    z.edges.clear();
    let (depth, seq) = (&mut z.depth[..], &mut z.seq[..]);
    for chunk in chunks {
        let run = chunk.starts[band] as usize..chunk.starts[band + 1] as usize;
        for e in chunk.entries[run].iter().filter(|e| e.covers_centres()) {
            let tri = t.triangles[e.triangle as usize];
            let Some(s) = edges(tri.map(|v| t.verts[v as usize].c), e.triangle) else {
                continue;
            };
            // Triangles are met in the order of their index, and an equal depth does not
            // replace: of equally near triangles the lowest index stays.
            let sid = z.edges.len() as u32;
            z.edges.push(s);
            let [n0, n1, n2] = s.n;
            let (o0, o1, o2) = (s.owns & 1 != 0, s.owns & 2 != 0, s.owns & 4 != 0);
            let y0 = usize::from(e.y0).max(y_first);
            let y1 = usize::from(e.y1).min(y_first + rows - 1);
            let (x0, x1) = (usize::from(e.x0), usize::from(e.x1));
            for y in y0..=y1 {
                let sy = t.sy[y];
                let r = [n0[1] * sy + n0[2], n1[1] * sy + n1[2], n2[1] * sy + n2[2]];
                let (x0, x1) = if x1 - x0 + 1 >= SPAN_MIN_WIDTH {
                    match row_span(t, &s.n, r, x0, x1) {
                        Some(span) => span,
                        None => continue,
                    }
                } else {
                    (x0, x1)
                };
                let row = (y - y_first) * pitch;
                let cells = depth[row + x0..=row + x1]
                    .iter_mut()
                    .zip(&mut seq[row + x0..=row + x1]);
                for (sx, (d, k)) in t.sx[x0..=x1].iter().zip(cells) {
                    let w0 = n0[0] * sx + r[0];
                    let w1 = n1[0] * sx + r[1];
                    let w2 = n2[0] * sx + r[2];
                    // Strictly inside all three edges, or (rarely) on an edge and owning it.
                    let m = min(min(w0, w1), w2);
                    let covered =
                        (m > 0.0) | (m == 0.0 && inside(w0, o0) & inside(w1, o1) & inside(w2, o2));
                    // Branch-free from here: whether a small triangle covers a pixel is
                    // unpredictable.
                    let q = (w0 + w1 + w2) * s.inv_det;
                    let wins = covered & (q > *d) & (q <= t.q_near);
                    *d = if wins { q } else { *d };
                    *k = if wins { sid } else { *k };
                }
            }
        }
    }
    let rays = t.rays;
    for (r, (frags, (depth, seq))) in out
        .chunks_mut(width)
        .zip(z.depth.chunks(pitch).zip(z.seq.chunks(pitch)))
        .enumerate()
    {
        let sy = t.sy[y_first + r];
        // |forward + right sx + up sy|^2 = |b|^2 + 2 sx b.right + sx^2 |right|^2, b the row's
        // forward + up sy.
        let b = std::array::from_fn(|i| rays.forward[i] + rays.up[i] * sy);
        let (bb, br, rr) = (
            dot(b, b),
            2.0 * dot(b, rays.right),
            dot(rays.right, rays.right),
        );
        for (x, frag) in frags.iter_mut().enumerate() {
            if seq[x] == NONE {
                *frag = Fragment::EMPTY;
                continue;
            }
            let s = &z.edges[seq[x] as usize];
            let sx = t.sx[x];
            // The same edge values as the coverage test; their sum is q |det| = q / inv_det,
            // and each over the sum is its vertex's weight.
            let (w1, w2) = (
                s.n[1][0] * sx + (s.n[1][1] * sy + s.n[1][2]),
                s.n[2][0] * sx + (s.n[2][1] * sy + s.n[2][2]),
            );
            let inv_q = 1.0 / depth[x];
            let per_sum = s.inv_det * inv_q;
            let length = (bb + sx * (br + sx * rr)).sqrt();
            *frag = Fragment {
                triangle: s.triangle,
                bary: [(w1 * per_sum) as f32, (w2 * per_sum) as f32],
                // The hit is at depth z = 1 / q along forward + right sx + up sy.
                distance: (length * inv_q) as f32,
            };
        }
    }
}

pub(crate) mod samples;
#[cfg(test)]
mod tests;

//! Synthetic per-vertex bake files written with the container writer alone (no baker): a
//! mesh, materials, groups whose tensors the tests fill in from definitions, and helpers that
//! compute what the runtime should give independently of it. The file writer is in
//! `write.rs`.

use std::path::Path;

use half::f16;
use prt_formats::basis::{HemiGrid, ParamWarp, ShadingBasis, TuckerRanks, SHADING_SCHEMA_VERSION};
use prt_formats::lighting::cubemap::{face_solid_angles, texel_centre_direction};
use prt_formats::lighting::{Face, HaarCube};
use prt_formats::pixel::{CameraMeta, MaterialMeta, Precision, SlotKind};
use prt_formats::vertex::{
    cube_len, names, shading_tables, to_local, vertex_frame, EnvironmentMeta, ShadingMeta,
    TextureMeta, VertexBakeMeta, VertexBakeStats, VertexGroupMeta, DIRECT_CUBE, SH_TERMS,
    T1_LIGHT_CUBE, T2_LIGHT_CUBE, VERTEX_SCHEMA_VERSION, VISIBILITY_CUBE,
};
use prt_formats::view::{CameraFrame, CameraSpec};
use prt_formats::{BakeWriter, Family};
use prt_runtime::{RenderStats, RuntimeError, VertexRelighter};

/// A triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub triangles: Vec<[u32; 3]>,
    pub triangle_material: Vec<u32>,
}

impl Mesh {
    /// An `n x n`-vertex grid over the square `[-1, 1]^2` of the plane through the origin
    /// with normal `normal` (one of +Y or +Z), material `material`.
    pub fn grid(n: usize, normal: [f32; 3], material: u32) -> Mesh {
        let mut m = Mesh::default();
        for r in 0..n {
            for c in 0..n {
                let a = -1.0 + 2.0 * c as f32 / (n - 1) as f32;
                let b = -1.0 + 2.0 * r as f32 / (n - 1) as f32;
                m.positions.push(if normal[1] > 0.5 {
                    [a, 0.0, b]
                } else {
                    [a, b, 0.0]
                });
                m.normals.push(normal);
                m.uvs.push([(a + 1.0) / 2.0, (b + 1.0) / 2.0]);
            }
        }
        for r in 0..n - 1 {
            for c in 0..n - 1 {
                let i = (r * n + c) as u32;
                let n = n as u32;
                m.triangles.push([i, i + 1, i + n + 1]);
                m.triangles.push([i, i + n + 1, i + n]);
                m.triangle_material.extend([material, material]);
            }
        }
        m
    }

    /// The quad `[-1, 1]^2` facing `normal` (+Y or +Z): 4 vertices, 2 triangles.
    pub fn quad(normal: [f32; 3], material: u32) -> Mesh {
        Mesh::grid(2, normal, material)
    }

    /// A closed axis-aligned box `[-1, 1]^3`, normals outwards, 4 vertices per face.
    pub fn closed_box(material: u32) -> Mesh {
        let mut m = Mesh::default();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let mut n = [0.0f32; 3];
                n[axis] = sign;
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let base = m.positions.len() as u32;
                for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    let mut p = [0.0f32; 3];
                    p[axis] = sign;
                    p[u] = a;
                    p[v] = b;
                    m.positions.push(p);
                    m.normals.push(n);
                    m.uvs.push([0.0, 0.0]);
                }
                m.triangles.push([base, base + 1, base + 2]);
                m.triangles.push([base, base + 2, base + 3]);
                m.triangle_material.extend([material, material]);
            }
        }
        m
    }
}

/// One group's data as stored (values before the group's scales).
#[derive(Clone, Debug)]
pub struct Group {
    pub vertices: Vec<u32>,
    /// `[V_g, rows, terms]`.
    pub t0_index: Vec<u16>,
    pub t0_value: Vec<f32>,
    pub t0_shape: [usize; 3],
    /// `[V_g, 1536]`.
    pub visibility: Vec<u8>,
    /// `[V_g]`: 1 where the irradiance row is the occluded part (schema 4).
    pub t0_open: Vec<u8>,
    /// `[V_g, 384, J, 16, channels]`.
    pub t1: Vec<f32>,
    pub t1_shape: [usize; 5],
    /// T1 as stored f16 values, used instead of `t1` when T1 is stored as f16 (large bakes).
    pub t1_f16: Option<Vec<f16>>,
    /// `[V_g, 24, J, I, channels]` (reflections = 3).
    pub t2: Vec<f32>,
    pub t2_shape: [usize; 5],
}

impl Group {
    /// A group of `vertices` with zero T1 and T2 of `j` active slots, `i` T2 slots and
    /// `channels` channels, all texels visible, and T0 rows given per vertex
    /// (`rows x terms` Haar coefficients each, indices `0..terms`).
    pub fn new(
        vertices: Vec<u32>,
        t0_rows: &[Vec<Vec<f32>>],
        j: usize,
        i: usize,
        channels: usize,
    ) -> Group {
        let nv = vertices.len();
        let rows = t0_rows.first().map_or(1, |r| r.len());
        let terms = t0_rows
            .first()
            .and_then(|r| r.first())
            .map_or(1, |t| t.len());
        let mut t0_index = Vec::with_capacity(nv * rows * terms);
        let mut t0_value = Vec::with_capacity(nv * rows * terms);
        for v in t0_rows {
            for row in v {
                t0_index.extend((0..terms).map(|t| t as u16));
                t0_value.extend(row);
            }
        }
        let t1_shape = [nv, cube_len(T1_LIGHT_CUBE), j, SH_TERMS, channels];
        let t2_shape = [nv, cube_len(T2_LIGHT_CUBE), j, i, channels];
        Group {
            vertices,
            t0_index,
            t0_value,
            t0_shape: [nv, rows, terms],
            visibility: vec![255; nv * cube_len(VISIBILITY_CUBE)],
            t0_open: vec![0; nv],
            t1: vec![0.0; t1_shape.iter().product()],
            t1_shape,
            t1_f16: None,
            t2: vec![0.0; t2_shape.iter().product()],
            t2_shape,
        }
    }
}

/// A synthetic per-vertex bake.
#[derive(Clone, Debug)]
pub struct Bake {
    pub meta: VertexBakeMeta,
    pub mesh: Mesh,
    pub groups: Vec<Group>,
    /// Full shading bases (tables included); the metadata's copies are emptied on writing.
    pub shading: Vec<ShadingBasis>,
    /// `[h, w, 3]` flat, one per `meta.textures`.
    pub textures: Vec<Vec<f32>>,
    /// `[h, w, 3]` flat when `meta.environment` is a lat-long map.
    pub environment: Vec<f32>,
    /// Store T1 in this precision whatever the metadata says.
    pub t1_stored_as: Option<Precision>,
    /// Store T1 and T2 compressed (`prt_formats::clustered`) with identity light and element
    /// factors, the vertices of each group in two interleaved clusters (even and odd) with
    /// one-hot vertex rows, and the dense values as cores: the same tensors exactly, through
    /// the runtime's compressed path.
    pub compress_as_identity: bool,
    /// Changes the cluster of each vertex after the compressed tensors are made (a corrupt
    /// file for the refusal tests).
    pub tamper_clusters: Option<Tamper>,
}

/// Changes a compressed group's cluster of each vertex ([`Bake::tamper_clusters`]).
pub type Tamper = fn(&mut Vec<u32>);

/// A material with a Kd slot (and a fixed lobe slot for a glossy family).
pub fn material(
    name: &str,
    family: Family,
    kd: [f32; 3],
    ks: [f32; 3],
    param: f32,
) -> MaterialMeta {
    let slots = if family == Family::Diffuse {
        vec![SlotKind::Kd]
    } else {
        vec![SlotKind::Kd, SlotKind::Lobe]
    };
    MaterialMeta {
        name: name.to_string(),
        editable: true,
        family,
        kd,
        ks,
        param,
        textured: false,
        slots,
        slot_offset: 0,
        basis: None,
    }
}

/// Numbers the materials' slots globally.
pub fn number_slots(materials: &mut [MaterialMeta]) {
    let mut offset = 0;
    for m in materials {
        m.slot_offset = offset;
        offset += m.slots.len() as u32;
    }
}

/// A GGX shading basis with constant rows: residual `a` (1/sr) for every direction and
/// parameter, split widths 0, 7, 14, 21 degrees with reflectances `r` (also constant), so its
/// albedo under a constant environment is `pi a + sum r`. `u_o` is `wo.z` at the nodes
/// (the pole row 1) when `view_dependent`.
pub fn constant_basis(a: f32, r: [f32; 4], view_dependent: bool) -> ShadingBasis {
    let dirs = HemiGrid {
        n_theta: 8,
        n_phi: 16,
    };
    let nd = dirs.len();
    let params = vec![0.05f32, 0.5, 1.0];
    let np = params.len();
    let u_o = if view_dependent {
        (0..nd).map(|n| dirs.dir(n)[2] as f32).collect()
    } else {
        vec![1.0; nd]
    };
    ShadingBasis {
        version: SHADING_SCHEMA_VERSION,
        family: Family::Ggx,
        method: "test: constant rows".into(),
        param_range: [0.05, 1.0],
        param_warp: ParamWarp::Linear,
        param_samples: params,
        dirs,
        ranks: TuckerRanks { h: 1, o: 1, i: 1 },
        u_h: vec![a; np],
        u_o,
        u_o_pole: vec![1.0],
        u_i: vec![1.0; nd],
        u_i_pole: vec![1.0],
        core: vec![1.0],
        split_widths_deg: vec![0.0, 7.0, 14.0, 21.0],
        reflectances: (0..np * nd).flat_map(|_| r).collect(),
        reflectances_pole: (0..np).flat_map(|_| r).collect(),
    }
}

/// `(direction, solid angle)` of every texel of the 6x64x64 cube, in storage order.
pub fn direct_texels() -> Vec<([f64; 3], f64)> {
    let omega = face_solid_angles(DIRECT_CUBE);
    let mut out = Vec::with_capacity(cube_len(DIRECT_CUBE));
    for face in Face::ALL {
        for j in 0..DIRECT_CUBE {
            for i in 0..DIRECT_CUBE {
                out.push((
                    texel_centre_direction(DIRECT_CUBE, face, i, j),
                    omega[j * DIRECT_CUBE + i],
                ));
            }
        }
    }
    out
}

/// T0 rows of an unoccluded vertex with normal `n`, from the definition: `U^i(w_local, k)
/// (w . n)+` for the basis' rows, then `(w . n)+`, at the 64-cube's texel centres,
/// area-weighted Haar transformed, every term kept.
pub fn t0_rows(n: [f32; 3], basis: Option<&ShadingBasis>) -> Vec<Vec<f32>> {
    let haar = HaarCube::new(DIRECT_CUBE).expect("haar");
    let (t, b) = vertex_frame(n);
    let texels = direct_texels();
    let rank = basis.map_or(0, |b| b.ranks.i);
    let mut rows = vec![vec![0.0f64; texels.len()]; rank + 1];
    let mut ui = [0.0f32; 32];
    for (k, (d, _)) in texels.iter().enumerate() {
        let d32 = d.map(|c| c as f32);
        let cos = (d32[0] * n[0] + d32[1] * n[1] + d32[2] * n[2]).max(0.0) as f64;
        if cos <= 0.0 {
            continue;
        }
        if let Some(bs) = basis {
            bs.u_i_row(to_local(t, b, n, d32), &mut ui);
            for c in 0..rank {
                rows[c][k] = ui[c] as f64 * cos;
            }
        }
        rows[rank][k] = cos;
    }
    rows.iter()
        .map(|r| {
            haar.forward_f64(r)
                .expect("haar")
                .iter()
                .map(|&x| x as f32)
                .collect()
        })
        .collect()
}

/// `integral (w . n)+ dw` by the 64-cube's midpoint rule: the irradiance of a unit
/// environment the T0 rows of [`t0_rows`] give.
pub fn cube_cosine_integral(n: [f32; 3]) -> f64 {
    direct_texels()
        .iter()
        .map(|(d, w)| (d[0] * n[0] as f64 + d[1] * n[1] as f64 + d[2] * n[2] as f64).max(0.0) * w)
        .sum()
}

/// The camera looking at the origin from `eye`.
pub fn camera(eye: [f32; 3], fov: f32) -> CameraFrame {
    CameraSpec {
        eye,
        target: [0.0, 0.0, 0.0],
        fov_deg: fov,
    }
    .frame()
    .expect("camera")
}

impl Bake {
    /// Sets group `g`'s own count of T0 terms (schema 3) in the metadata only.
    pub fn groups_meta_t0_terms(&mut self, g: usize, terms: u32) {
        self.meta.groups[g].t0_terms = Some(terms);
    }

    /// Keeps only the first `k` terms of every T0 row of group `g`: stored as `k` terms with
    /// the group's own count (schema 3) when `own_count`, else padded back to the bake's count
    /// with (index 0, value 0) as an older writer would. Both say the same.
    pub fn cut_t0(&mut self, g: usize, k: usize, own_count: bool) {
        let group = &mut self.groups[g];
        let terms = group.t0_shape[2];
        let (mut index, mut value) = (Vec::new(), Vec::new());
        for (i, v) in group
            .t0_index
            .chunks_exact(terms)
            .zip(group.t0_value.chunks_exact(terms))
        {
            index.extend_from_slice(&i[..k]);
            value.extend_from_slice(&v[..k]);
            if !own_count {
                index.extend(std::iter::repeat_n(0u16, terms - k));
                value.extend(std::iter::repeat_n(0.0f32, terms - k));
            }
        }
        group.t0_index = index;
        group.t0_value = value;
        if own_count {
            group.t0_shape[2] = k;
            self.meta.groups[g].t0_terms = Some(k as u32);
        }
    }

    /// One group per material over the mesh's vertices of that material, materials as
    /// given (slots numbered here), a constant environment, the tensors' scales 1.
    pub fn new(
        mesh: Mesh,
        mut materials: Vec<MaterialMeta>,
        groups: Vec<(u32, Group, Option<u32>)>,
        shading: Vec<ShadingBasis>,
        radiance: [f32; 3],
    ) -> Bake {
        number_slots(&mut materials);
        let group_meta = groups
            .iter()
            .map(|(m, g, s)| VertexGroupMeta {
                material: *m,
                vertices: g.vertices.len() as u32,
                t0_rows: g.t0_shape[1] as u32,
                shading: *s,
                active: (0..g.t1_shape[2] as u32).collect(),
                scale_t0: 1.0,
                scale_t1: 1.0,
                scale_t2: 1.0,
                compression: None,
                t0_terms: None,
            })
            .collect();
        let n_i = groups.first().map_or(0, |g| g.1.t2_shape[3]);
        let channels = groups.first().map_or(1, |g| g.1.t1_shape[4]) as u32;
        let terms = groups.first().map_or(1, |g| g.1.t0_shape[2]) as u32;
        let nm = materials.len();
        Bake {
            meta: VertexBakeMeta {
                vertex_schema_version: VERTEX_SCHEMA_VERSION,
                vertices: mesh.positions.len() as u32,
                triangles: mesh.triangles.len() as u32,
                samples: 1,
                secondary: 1,
                light_bins: false,
                reflections: 2,
                seed: 1,
                channels,
                precision: Precision::F32,
                t0_terms: terms,
                materials,
                bases: Vec::new(),
                shading: shading
                    .iter()
                    .map(|b| {
                        let mut basis = b.clone();
                        for (_, t) in prt_formats::vertex::shading_tables_mut(&mut basis) {
                            t.clear();
                        }
                        ShadingMeta { basis }
                    })
                    .collect(),
                textures: Vec::new(),
                material_textures: vec![None; nm],
                material_normal_maps: Vec::new(),
                t2_slots: (0..n_i as u32).collect(),
                groups: group_meta,
                environment: EnvironmentMeta::Constant { radiance },
                camera: CameraMeta {
                    position: [0.0, 2.0, 2.0],
                    forward: [
                        0.0,
                        -std::f32::consts::FRAC_1_SQRT_2,
                        -std::f32::consts::FRAC_1_SQRT_2,
                    ],
                    up: [
                        0.0,
                        std::f32::consts::FRAC_1_SQRT_2,
                        -std::f32::consts::FRAC_1_SQRT_2,
                    ],
                    yfov: 0.7,
                },
                stats: VertexBakeStats::default(),
                compression: None,
            },
            mesh,
            groups: groups.into_iter().map(|(_, g, _)| g).collect(),
            shading,
            textures: Vec::new(),
            environment: Vec::new(),
            t1_stored_as: None,
            compress_as_identity: false,
            tamper_clusters: None,
        }
    }

    /// Lights the bake with a lat-long map (`[h, w, 3]` flat).
    pub fn set_latlong(&mut self, width: usize, height: usize, texels: Vec<f32>, rotation: f32) {
        self.meta.environment = EnvironmentMeta::LatLong {
            width: width as u32,
            height: height as u32,
            rotation_deg: rotation,
        };
        self.environment = texels;
    }

    /// Gives material `m` a texture (`[h, w, 3]` flat).
    pub fn set_texture(&mut self, m: usize, width: usize, height: usize, texels: Vec<f32>) {
        self.meta.material_textures[m] = Some(self.textures.len() as u32);
        self.meta.textures.push(TextureMeta {
            width: width as u32,
            height: height as u32,
        });
        self.textures.push(texels);
    }
}

/// A lat-long map `[h, w, 3]` flat: dim sky, a bright warm patch towards -Z above the
/// horizon and a blue one towards +X below it, so every rotation about +Y changes it.
pub fn asymmetric_map(width: usize, height: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(width * height * 3);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (
                (x as f32 + 0.5) / width as f32,
                (y as f32 + 0.5) / height as f32,
            );
            let mut c = [0.2f32, 0.25, 0.3];
            if (0.4..0.6).contains(&u) && (0.2..0.45).contains(&v) {
                c = [6.0, 4.0, 1.5];
            }
            if (0.7..0.8).contains(&u) && (0.55..0.7).contains(&v) {
                c = [0.5, 1.0, 5.0];
            }
            out.extend(c);
        }
    }
    out
}

/// Renders the view of `cam` at `w` x `h` into `out`: the camera and size set, then the frame.
/// Antialiasing is off: these tests hold each pixel, by where its centre's ray meets the
/// geometry, to a closed form (a pixel an outline crosses would be the average of what it
/// holds; the antialiasing has its own tests in `runtime/src/vertex/raster/tests/samples.rs`
/// and `tests/tests/suite/vertex_antialias.rs`).
pub fn frame(
    r: &mut VertexRelighter,
    cam: &CameraFrame,
    w: u32,
    h: u32,
    out: &mut [f32],
) -> Result<RenderStats, RuntimeError> {
    r.set_antialias(false);
    r.set_size(w, h)?;
    r.set_camera(*cam)?;
    r.render_into(out)
}

/// Renders and returns the RGB image.
pub fn render(r: &mut VertexRelighter, cam: &CameraFrame, w: u32, h: u32) -> Vec<f32> {
    let mut out = vec![0.0f32; 3 * (w * h) as usize];
    frame(r, cam, w, h, &mut out).expect("render");
    out
}

/// One `--set` edit of material `name`, as `relight` makes it.
pub fn set(r: &mut VertexRelighter, edit: &str) -> Result<(), RuntimeError> {
    let o: prt_formats::MaterialOverride = edit.parse().expect("valid --set syntax");
    r.set_params(&o.material, &[o.value])
}

/// Where pixel `(x, y)`'s ray meets the plane through the origin with normal `n`
/// (`None` when behind the eye or parallel).
pub fn hit_plane(
    cam: &CameraFrame,
    w: u32,
    h: u32,
    x: u32,
    y: u32,
    n: [f32; 3],
) -> Option<[f64; 3]> {
    let d = pixel_direction(cam, w, h, x, y).map(f64::from);
    let e = cam.position.map(f64::from);
    let n = n.map(f64::from);
    let dn = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
    let en = e[0] * n[0] + e[1] * n[1] + e[2] * n[2];
    if dn.abs() < 1e-12 {
        return None;
    }
    let t = -en / dn;
    (t > 0.0).then(|| std::array::from_fn(|i| e[i] + t * d[i]))
}

/// The unit view direction through the centre of pixel `(x, y)`, by the film formula of
/// docs/conventions.md ("Camera"), in f64 and then rounded to f32 as the runtime's is.
pub fn pixel_direction(cam: &CameraFrame, w: u32, h: u32, x: u32, y: u32) -> [f32; 3] {
    let (fx, fy) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
    let (w, h) = (f64::from(w), f64::from(h));
    let t = (f64::from(cam.yfov) * 0.5).tan();
    let sx = (2.0 * fx / w - 1.0) * t * (w / h);
    let sy = (1.0 - 2.0 * fy / h) * t;
    let d: [f64; 3] = std::array::from_fn(|i| {
        f64::from(cam.forward[i]) + f64::from(cam.right[i]) * sx + f64::from(cam.up[i]) * sy
    });
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    d.map(|c| (c / len) as f32)
}

/// A 12 x 12 glossy, textured grid (f16) under an asymmetric lat-long environment: the view
/// stage's lobe, texture, visibility and background paths.
pub fn glossy_grid() -> Bake {
    let up = [0.0, 1.0, 0.0];
    let basis = constant_basis(0.06, [0.2, 0.1, 0.05, 0.05], true);
    let mesh = Mesh::grid(12, up, 0);
    let nv = mesh.positions.len();
    let row = t0_rows(up, Some(&basis));
    let rows: Vec<_> = (0..nv).map(|_| row.clone()).collect();
    let mut g = Group::new((0..nv as u32).collect(), &rows, 3, 2, 1);
    for (k, x) in g.t1.iter_mut().chain(g.t2.iter_mut()).enumerate() {
        *x = 0.01 * (k % 5) as f32;
    }
    for (k, v) in g.visibility.iter_mut().enumerate() {
        *v = ((k * 7) % 256) as u8;
    }
    // The second material has no triangles; it gives the group the slot count of the
    // vertex tests' busy bake.
    let materials = vec![
        material("metal", Family::Ggx, [0.3, 0.4, 0.2], [0.8, 0.6, 0.4], 0.3),
        material("wall", Family::Diffuse, [0.6, 0.2, 0.2], [0.0; 3], 0.0),
    ];
    let mut bake = Bake::new(
        mesh,
        materials,
        vec![(0, g, Some(0))],
        vec![basis],
        [1.0; 3],
    );
    bake.meta.precision = Precision::F16;
    bake.meta.reflections = 3;
    bake.set_latlong(64, 32, asymmetric_map(64, 32), 10.0);
    let texels = (0..8 * 8 * 3).map(|k| 0.2 + 0.1 * (k % 7) as f32).collect();
    bake.set_texture(0, 8, 8, texels);
    bake
}

mod write;

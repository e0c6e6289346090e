//! Writing a synthetic [`Bake`] with the container writer: its metadata and tensors as the
//! baker would store them (dense, or as an identity-factor compression), f32 or f16.

use super::*;

impl Bake {
    /// Writes the file. Stored values are the groups' as given (f16 when the metadata says
    /// so); shapes are the data's own, so a corrupted metadata field stays corrupt.
    pub fn write(&self, path: &Path) {
        let halves = |v: &[f32]| -> Vec<f16> { v.iter().map(|&x| f16::from_f32(x)).collect() };
        let precision = self.meta.precision;
        let t1_precision = self.t1_stored_as.unwrap_or(precision);
        let h16: Vec<[Vec<f16>; 3]> = self
            .groups
            .iter()
            .map(|g| {
                let t1 = match &g.t1_f16 {
                    Some(_) => Vec::new(),
                    None => halves(&g.t1),
                };
                [halves(&g.t0_value), t1, halves(&g.t2)]
            })
            .collect();
        let m = &self.mesh;
        let flat3 = |v: &[[f32; 3]]| -> Vec<f32> { v.iter().flatten().copied().collect() };
        let positions = flat3(&m.positions);
        let normals = flat3(&m.normals);
        let uvs: Vec<f32> = m.uvs.iter().flatten().copied().collect();
        let tris: Vec<u32> = m.triangles.iter().flatten().copied().collect();
        let nv = m.positions.len();
        let nt = m.triangles.len();
        // Compressed groups: the tensors and the metadata that describes them.
        let mut meta = self.meta.clone();
        let mut compressed = Vec::new();
        if self.compress_as_identity {
            for (gm, gd) in meta.groups.iter_mut().zip(&self.groups) {
                let nv_g = gd.vertices.len();
                let clusters: Vec<u32> = (0..nv_g).map(|v| (v % 2) as u32).collect();
                let k = nv_g.min(2);
                let mut tensors = Vec::new();
                let mut shapes = vec![(&gd.t1, gd.t1_shape)];
                if meta.reflections >= 3 {
                    shapes.push((&gd.t2, gd.t2_shape));
                }
                for (t, shape) in shapes {
                    let width = shape[2] * shape[3] * shape[4];
                    tensors.push(identity_tucker(t, &clusters, k, shape[1], width));
                }
                let figures = |b: usize| prt_formats::clustered::TensorCompression {
                    vertex_rank: b as u32,
                    error: 0.0,
                    noise: None,
                    beyond_noise: None,
                };
                gm.compression = Some(prt_formats::clustered::GroupCompression {
                    clusters: k as u32,
                    t1: figures(tensors[0].4),
                    t2: tensors.get(1).map(|t| figures(t.4)),
                });
                let halves = tensors
                    .iter()
                    .map(|t| [halves(&t.1), halves(&t.2), halves(&t.3)])
                    .collect::<Vec<_>>();
                let mut clusters = clusters;
                if let Some(tamper) = self.tamper_clusters {
                    tamper(&mut clusters);
                }
                compressed.push((clusters, tensors, halves));
            }
        }
        let mut w = BakeWriter::new();
        w.add_f32(names::POSITIONS, &[nv, 3], &positions)
            .expect("positions");
        w.add_f32(names::NORMALS, &[nv, 3], &normals)
            .expect("normals");
        w.add_f32(names::UVS, &[uvs.len() / 2, 2], &uvs)
            .expect("uvs");
        w.add_u32(names::TRIANGLES, &[nt, 3], &tris)
            .expect("triangles");
        w.add_u32(names::TRIANGLE_MATERIAL, &[nt], &m.triangle_material)
            .expect("triangle materials");
        for (g, (gd, h)) in self.groups.iter().zip(&h16).enumerate() {
            w.add_u32(&names::vertices(g), &[gd.vertices.len()], &gd.vertices)
                .expect("vertices");
            w.add_u16(&names::t0_index(g), &gd.t0_shape, &gd.t0_index)
                .expect("t0 index");
            add_values(
                &mut w,
                precision,
                &names::t0_value(g),
                &gd.t0_shape,
                &gd.t0_value,
                &h[0],
            );
            w.add_u8(
                &names::visibility(g),
                &[gd.vertices.len(), cube_len(VISIBILITY_CUBE)],
                &gd.visibility,
            )
            .expect("visibility");
            if self.meta.vertex_schema_version >= 4 {
                w.add_u8(&names::t0_open(g), &[gd.vertices.len()], &gd.t0_open)
                    .expect("t0 open");
            }
            if let Some((clusters, tensors, halves)) = compressed.get(g) {
                w.add_u32(&names::clusters(g), &[clusters.len()], clusters)
                    .expect("clusters");
                for ((tensor, t), h) in [names::T1, names::T2].iter().zip(tensors).zip(halves) {
                    let name = |part| names::tucker(g, tensor, part);
                    w.add_u32(&name(names::TUCKER_RANKS), &[t.0.len() / 3, 3], &t.0)
                        .expect("ranks");
                    add_values(
                        &mut w,
                        precision,
                        &name(names::TUCKER_FACTORS),
                        &[t.1.len()],
                        &t.1,
                        &h[0],
                    );
                    add_values(
                        &mut w,
                        precision,
                        &name(names::TUCKER_CORE),
                        &[t.2.len()],
                        &t.2,
                        &h[1],
                    );
                    add_values(
                        &mut w,
                        precision,
                        &name(names::TUCKER_VERTEX),
                        &[clusters.len(), t.4],
                        &t.3,
                        &h[2],
                    );
                }
                continue;
            }
            let t1_16 = gd.t1_f16.as_deref().unwrap_or(&h[1]);
            add_values(
                &mut w,
                t1_precision,
                &names::t1(g),
                &gd.t1_shape,
                &gd.t1,
                t1_16,
            );
            if self.meta.reflections >= 3 {
                add_values(
                    &mut w,
                    precision,
                    &names::t2(g),
                    &gd.t2_shape,
                    &gd.t2,
                    &h[2],
                );
            }
        }
        for (b, basis) in self.shading.iter().enumerate() {
            for (table, data) in shading_tables(basis) {
                w.add_f32(&names::shading_table(b, table), &[data.len()], data)
                    .expect("shading table");
            }
        }
        for (t, (tm, data)) in self.meta.textures.iter().zip(&self.textures).enumerate() {
            w.add_f32(
                &names::texture(t),
                &[tm.height as usize, tm.width as usize, 3],
                data,
            )
            .expect("texture");
        }
        if let EnvironmentMeta::LatLong { width, height, .. } = self.meta.environment {
            w.add_f32(
                names::ENVIRONMENT,
                &[height as usize, width as usize, 3],
                &self.environment,
            )
            .expect("environment");
        }
        w.set_metadata(serde_json::to_value(&meta).expect("metadata"));
        w.write_atomic(path).expect("write synthetic vertex bake");
    }
}

/// A dense `[V][bins][width]` tensor as an exact clustered Tucker product (see
/// [`Bake::compress_as_identity`]): ranks `[K, 3]`, factors, cores, vertex rows `[V, B]`.
fn identity_tucker(
    t: &[f32],
    clusters: &[u32],
    k: usize,
    bins: usize,
    width: usize,
) -> (Vec<u32>, Vec<f32>, Vec<f32>, Vec<f32>, usize) {
    let members: Vec<Vec<usize>> = (0..k)
        .map(|c| {
            (0..clusters.len())
                .filter(|&v| clusters[v] as usize == c)
                .collect()
        })
        .collect();
    let b_max = members.iter().map(|m| m.len()).max().unwrap_or(0);
    let (mut ranks, mut factors, mut core) = (Vec::new(), Vec::new(), Vec::new());
    let mut vertex = vec![0.0f32; clusters.len() * b_max];
    for m in &members {
        ranks.extend([bins as u32, width as u32, m.len() as u32]);
        for n in [bins, width] {
            for i in 0..n {
                factors.extend((0..n).map(|j| if i == j { 1.0 } else { 0.0 }));
            }
        }
        for (b, &v) in m.iter().enumerate() {
            core.extend_from_slice(&t[v * bins * width..(v + 1) * bins * width]);
            vertex[v * b_max + b] = 1.0;
        }
    }
    (ranks, factors, core, vertex, b_max)
}

/// Adds a values tensor as f32 or f16.
fn add_values<'a>(
    w: &mut BakeWriter<'a>,
    p: Precision,
    name: &str,
    shape: &[usize],
    f: &'a [f32],
    h: &'a [f16],
) {
    match p {
        Precision::F32 => w.add_f32(name, shape, f),
        Precision::F16 => w.add_f16(name, shape, h),
    }
    .expect("values");
}

//! The per-pixel bake schema (docs/format.md, "Bake schema"): what the baker writes and the
//! runtime reads, and the one place that turns material parameters into slot coefficients.
//!
//! A pixel's radiance is a polynomial in the slot coefficients of the materials along its
//! paths (docs/pixel.md). Every material has a list of *slots*, functions its BRDF is a
//! combination of:
//!
//! - [`SlotKind::Kd`]: the Lambert lobe 1/pi, coefficient Kd (the diffuse texture multiplies
//!   it: per pixel by the runtime at the visible point, baked in at later bounces);
//! - [`SlotKind::Basis`]: basis BRDF b of the material's family (editable materials),
//!   coefficient Ks a_b(param), plus Kd for b = 0 when the material has no separate Kd slot;
//! - [`SlotKind::Lobe`]: the fixed specular lobe of a non-editable glossy material,
//!   coefficient Ks;
//! - [`SlotKind::Own`]: the whole BRDF of a non-editable material whose parameters vary over
//!   its surface (a glTF metallicRoughnessTexture), colours included, coefficient 1.
//!
//! Slots of all materials are numbered globally (`MaterialMeta::slot_offset`). For each
//! material R0 seen by the camera there is a *group*: its pixels and, per pixel, the tensors
//! T0\[b0\], T1\[b0, j1\], T2\[b0, j1, j2\] over R0's slots b0 and the group's *active* global slots
//! j (slots that ever carry light into the group), each with `channels` values (1 = gray).
//! The radiance of a pixel is `emission + sum_g sum_e W_g[e] x_g[e]` where `x_g` is the
//! pixel's flattened tensor and `W_g` the products of coefficients ([`group_weights`]).

use serde::{Deserialize, Serialize};

use crate::basis::BrdfBasis;
use crate::family::Family;

/// Version of the per-pixel schema (inside the container's own schema version).
pub const PIXEL_SCHEMA_VERSION: u32 = 1;

/// One function a material's BRDF is a combination of (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind", content = "index")]
pub enum SlotKind {
    /// The Lambert lobe 1/pi; coefficient Kd.
    Kd,
    /// Basis BRDF `b` of the material's family; coefficient Ks a_b(param) (plus Kd for b = 0
    /// when the material has no Kd slot).
    Basis(u32),
    /// The fixed specular lobe of a non-editable glossy material; coefficient Ks.
    Lobe,
    /// The whole BRDF of a non-editable material whose parameters vary over its surface
    /// (textures applied at each point, colours included); coefficient 1.
    Own,
}

/// One material of the scene as the bake file records it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialMeta {
    /// The material's name (from the glTF), as `--set` addresses it.
    pub name: String,
    /// Whether relighting may change its parameters.
    pub editable: bool,
    /// The material's BRDF family (stored by name: "diffuse", "blinn-phong" or "ggx").
    pub family: Family,
    /// The parameters the scene was baked with (the starting values of editable materials;
    /// the fixed values of the others).
    pub kd: [f32; 3],
    /// Specular albedo, linear RGB.
    pub ks: [f32; 3],
    /// The lobe parameter: shininess s (Blinn-Phong) or alpha (GGX); unused for diffuse.
    pub param: f32,
    /// Whether a base-colour texture modulates Kd.
    pub textured: bool,
    /// The functions the material's BRDF is a combination of, in slot order.
    pub slots: Vec<SlotKind>,
    /// Global index of this material's first slot.
    pub slot_offset: u32,
    /// Index into `PixelBakeMeta::bases` for editable glossy materials.
    pub basis: Option<u32>,
}

/// A family's basis as stored: everything but its large tables, which are the tensor
/// `basis.<index>.tables` (the runtime needs only the coefficient table).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BasisMeta {
    /// The basis with `tables` emptied.
    pub basis: BrdfBasis,
}

/// The pixels of the image where material `material` is visible, and their tensors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroupMeta {
    /// Index of the material into [`PixelBakeMeta::materials`].
    pub material: u32,
    /// Number of pixels in the group (rows of its tensors).
    pub pixels: u32,
    /// Number of slots of the material (b0).
    pub slots: u32,
    /// Global slots j that carry light into this group, ascending.
    pub active: Vec<u32>,
    /// Values per pixel: slots * (1 + J + J^2 ...) * channels, J = active.len(), up to
    /// `reflections - 1` factors of J.
    pub row_len: u32,
    /// Rank of the low-rank (PCA over pixels) variant, when the file has one.
    pub compressed_rank: Option<u32>,
    /// Stored value = true value / scale (f16 storage keeps the largest magnitude at 2^14 so
    /// sun-like dynamic range cannot overflow); 1 for f32 storage.
    pub scale: f32,
}

/// Everything the runtime needs besides the tensors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PixelBakeMeta {
    /// [`PIXEL_SCHEMA_VERSION`] of the writer; readers reject other versions.
    pub pixel_schema_version: u32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel the tensors were estimated with.
    pub spp: u32,
    /// Film samples per path sample of the emission image (the radiance the camera sees
    /// directly: emitters, the environment) in the pixels where it varies across the pixel;
    /// the others use `spp`. `None` in files written before it was recorded, which used
    /// `spp` everywhere ([`PixelBakeMeta::emission_oversampling`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub emission_oversampling: Option<u32>,
    /// Reflections per path: 2 stores T0 and T1, 3 adds T2.
    pub reflections: u32,
    /// The seed of the random streams.
    pub seed: u64,
    /// 1 (gray tensors, colours all in coefficients) or 3 (RGB tensors).
    pub channels: u32,
    /// The lights' common colour, divided out of gray tensors and multiplied back in by
    /// [`group_weights`] (white for RGB tensors).
    pub tint: [f32; 3],
    /// The storage type of the transfer tensors (stored as "f32" or "f16").
    pub precision: Precision,
    /// Every material of the scene, in scene order (slots numbered globally across them).
    pub materials: Vec<MaterialMeta>,
    /// The bases of the editable glossy families ([`MaterialMeta::basis`] indexes them).
    pub bases: Vec<BasisMeta>,
    /// One group per material seen by the camera.
    pub groups: Vec<GroupMeta>,
    /// The camera the image was baked for.
    pub camera: CameraMeta,
    /// Figures of the bake that depend only on its inputs (never timings, so the same inputs
    /// give a byte-identical file).
    pub stats: BakeStats,
}

/// Storage type of the transfer tensors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// 32-bit floats: relighting is exact to float rounding.
    F32,
    /// 16-bit floats with a per-group scale ([`GroupMeta::scale`]): half the size; rounding is
    /// amplified by cancellation for sharp lobes (docs/pixel.md).
    F16,
}

impl Precision {
    /// "f32" or "f16", as stored.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F16 => "f16",
        }
    }
}

/// What a per-pixel bake did, as far as it is a function of the inputs alone. Timings are not
/// stored (they would make two bakes of the same inputs differ); the bake command reports them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BakeStats {
    /// Rays traced (camera, bounce and shadow rays).
    pub rays: u64,
    /// Values the dense accumulation held (every slot, before compaction).
    pub dense_values: u64,
    /// Values stored after compaction to the active slots.
    pub stored_values: u64,
    /// Why each material got the slots it has, and the tensors' channel count.
    pub allocation: Vec<String>,
    /// Triangles of the scene.
    pub triangles: u64,
}

/// Tensor names of the per-pixel schema (docs/format.md, "Bake schema"): the one place both
/// the baker and the runtime take them from.
pub mod names {
    /// Radiance reaching the camera without a reflection, `[H, W, 3]` f32.
    pub const EMISSION: &str = "emission";
    /// Group `g`'s pixel indices (`y * width + x`, ascending), `[pixels]` u32.
    pub fn pixels(g: usize) -> String {
        format!("g{g}.pixels")
    }
    /// Group `g`'s transfer rows, element-major `[row_len, pixels]`, f32 or f16.
    pub fn transfer(g: usize) -> String {
        format!("g{g}.t")
    }
    /// Group `g`'s low-rank variant: the mean row, `[row_len]` f32.
    pub fn mean(g: usize) -> String {
        format!("g{g}.mean")
    }
    /// Group `g`'s low-rank variant: the components, `[rank, row_len]` f32.
    pub fn components(g: usize) -> String {
        format!("g{g}.components")
    }
    /// Group `g`'s low-rank variant: per-pixel weights, `[rank, pixels]` f32.
    pub fn weights(g: usize) -> String {
        format!("g{g}.weights")
    }
    /// The tables of basis `b` (`[nodes, num_bases]` f32).
    pub fn basis_tables(b: usize) -> String {
        format!("basis.{b}.tables")
    }
}

/// The camera of a per-pixel bake (pinhole, world space).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraMeta {
    /// Eye position, world space.
    pub position: [f32; 3],
    /// Unit viewing direction.
    pub forward: [f32; 3],
    /// Unit up vector, orthogonal to `forward`.
    pub up: [f32; 3],
    /// Vertical field of view, radians.
    pub yfov: f32,
}

/// The parameters of one material as the user sets them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialParams {
    /// Diffuse albedo, linear RGB.
    pub kd: [f32; 3],
    /// Specular albedo, linear RGB.
    pub ks: [f32; 3],
    /// Shininess s or alpha (by the material's family).
    pub param: f32,
}

impl MaterialMeta {
    /// The parameters the material was baked with.
    pub fn params(&self) -> MaterialParams {
        MaterialParams {
            kd: self.kd,
            ks: self.ks,
            param: self.param,
        }
    }

    /// Whether the material has its own Kd slot (otherwise Kd folds into basis 0).
    pub fn has_kd_slot(&self) -> bool {
        self.slots.contains(&SlotKind::Kd)
    }
}

/// The RGB coefficient of every slot of `material` for parameters `p`. `lobe` holds the
/// family's lobe coefficients a_b(param) for editable glossy materials (from
/// [`BrdfBasis::coefficients`]). Returns one RGB triple per slot.
pub fn slot_coefficients(
    material: &MaterialMeta,
    p: &MaterialParams,
    lobe: &[f32],
) -> Vec<[f32; 3]> {
    let has_kd = material.has_kd_slot();
    material
        .slots
        .iter()
        .map(|s| match *s {
            SlotKind::Kd => p.kd,
            SlotKind::Lobe => p.ks,
            SlotKind::Own => [1.0; 3],
            SlotKind::Basis(b) => {
                let a = lobe.get(b as usize).copied().unwrap_or(0.0);
                let d = if b == 0 && !has_kd { p.kd } else { [0.0; 3] };
                [d[0] + p.ks[0] * a, d[1] + p.ks[1] * a, d[2] + p.ks[2] * a]
            }
        })
        .collect()
}

/// Number of values per pixel of a group (saturating at `usize::MAX`).
///
/// The cost does not grow with `reflections` (read from a file, it may be absurd): the sum
/// 1 + J + J^2 + ... stops once its terms vanish (J = 0) or it saturates (J >= 2, within 64
/// terms), and J = 1 is summed in closed form.
pub fn row_len(slots: usize, active: usize, reflections: usize, channels: usize) -> usize {
    let per_b0 = match active {
        _ if reflections == 0 => 0,
        0 => 1,
        1 => reflections,
        _ => {
            let mut sum = 0usize;
            let mut pow = 1usize;
            for _ in 0..reflections {
                sum = sum.saturating_add(pow);
                if sum == usize::MAX {
                    break;
                }
                pow = pow.saturating_mul(active);
            }
            sum
        }
    };
    slots.saturating_mul(per_b0).saturating_mul(channels)
}

/// Contraction weights of a group for the current coefficients: for each output channel c and
/// each element e of the pixel row, `W[c][e]`, such that the radiance is `sum_e W[c][e] x[e]`
/// (textures are baked into the Kd slot values, so no per-pixel factor remains).
/// Returns W, `3 * row_len` values (channel-major). `coeff` holds the RGB
/// coefficient of every global slot.
pub fn group_weights(
    group: &GroupMeta,
    material: &MaterialMeta,
    coeff: &[[f32; 3]],
    reflections: usize,
    channels: usize,
    tint: [f32; 3],
) -> Vec<f32> {
    let n0 = material.slots.len();
    let act: Vec<[f32; 3]> = group
        .active
        .iter()
        .map(|&j| coeff.get(j as usize).copied().unwrap_or([0.0; 3]))
        .collect();
    let jn = act.len();
    let len = row_len(n0, jn, reflections, channels);
    let mut w = vec![0.0f32; 3 * len];
    let base = material.slot_offset as usize;
    // Enumerate elements in storage order: depth blocks, then b0, then j1.. jk, then channel.
    let mut e = 0usize;
    let mut pow = 1usize;
    for depth in 0..reflections {
        if pow == 0 {
            // No active slots: no deeper terms (and no work for an absurd `reflections`).
            break;
        }
        for b0 in 0..material.slots.len() {
            let c0 = coeff.get(base + b0).copied().unwrap_or([0.0; 3]);
            for idx in 0..pow {
                // Product of the tint and the coefficients of the slots b0, j1..jdepth.
                let mut prod = [c0[0] * tint[0], c0[1] * tint[1], c0[2] * tint[2]];
                let mut rest = idx;
                for _ in 0..depth {
                    let j = rest % jn.max(1);
                    rest /= jn.max(1);
                    for ch in 0..3 {
                        prod[ch] *= act[j][ch];
                    }
                }
                if channels == 1 {
                    for ch in 0..3 {
                        w[ch * len + e] = prod[ch];
                    }
                    e += 1;
                } else {
                    for ch in 0..3 {
                        w[ch * len + e + ch] = prod[ch];
                    }
                    e += 3;
                }
            }
        }
        pow = pow.saturating_mul(jn);
    }
    debug_assert_eq!(e, len);
    w
}

/// Index of a T_k element within a group row: depth k, slot b0, active indices js (length k,
/// j1 first), channel ch. The storage order is the one [`group_weights`] enumerates: depth
/// blocks; within a block b0, then the active indices with j1 varying *fastest*, then channel.
pub fn element_index(
    n0: usize,
    jn: usize,
    channels: usize,
    b0: usize,
    js: &[usize],
    ch: usize,
) -> usize {
    let mut off = 0usize;
    let mut pow = 1usize;
    for _ in 0..js.len() {
        off += n0 * pow;
        pow *= jn;
    }
    let mut idx = 0usize;
    let mut mul = 1usize;
    for &j in js {
        idx += j * mul;
        mul *= jn;
    }
    (off + b0 * pow + idx) * channels + ch
}

impl PixelBakeMeta {
    /// Film samples per path sample of the emission image where it varies (1 where the file
    /// does not say).
    pub fn emission_oversampling(&self) -> u32 {
        self.emission_oversampling.unwrap_or(1)
    }

    /// The metadata as the JSON the file's `__metadata__` stores.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(slots: Vec<SlotKind>, textured: bool) -> MaterialMeta {
        MaterialMeta {
            name: "m".into(),
            editable: true,
            family: Family::BlinnPhong,
            kd: [0.5; 3],
            ks: [0.2; 3],
            param: 10.0,
            textured,
            slots,
            slot_offset: 0,
            basis: Some(0),
        }
    }

    #[test]
    fn coefficients_fold_kd_into_basis_zero_without_kd_slot() {
        let m = material(vec![SlotKind::Basis(0), SlotKind::Basis(1)], false);
        let p = MaterialParams {
            kd: [0.5, 0.4, 0.3],
            ks: [1.0, 2.0, 3.0],
            param: 5.0,
        };
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        let c = slot_coefficients(&m, &p, &[0.1, 0.2]);
        assert!(close(c[0], [0.6, 0.6, 0.6]), "{:?}", c[0]);
        assert!(close(c[1], [0.2, 0.4, 0.6]), "{:?}", c[1]);
        let mt = material(vec![SlotKind::Kd, SlotKind::Basis(0)], true);
        let c = slot_coefficients(&mt, &p, &[0.1]);
        assert_eq!(c[0], p.kd);
        assert!(close(c[1], [0.1, 0.2, 0.3]), "{:?}", c[1]);
    }

    /// Found by fuzzing (`prt-fuzz bake-file`): `reflections` = 2^31 - 1 in a file's metadata
    /// made `row_len` and `group_weights` loop 2^31 times (a hang in `Relighter::render`).
    #[test]
    fn absurd_reflections_cost_no_more_than_the_row() {
        assert_eq!(row_len(1, 0, usize::MAX, 1), 1);
        assert_eq!(row_len(2, 1, 1 << 40, 3), 6 << 40);
        assert_eq!(row_len(1, 2, usize::MAX, 1), usize::MAX);
        assert_eq!(row_len(1, 3, 4, 1), 1 + 3 + 9 + 27);
        assert_eq!(row_len(1, 3, 0, 1), 0);
        let m = material(vec![SlotKind::Kd], false);
        let g = GroupMeta {
            material: 0,
            pixels: 1,
            slots: 1,
            active: vec![],
            row_len: 1,
            compressed_rank: None,
            scale: 1.0,
        };
        let w = group_weights(&g, &m, &[[0.5; 3]], i32::MAX as usize, 1, [1.0; 3]);
        assert_eq!(w, [0.5; 3]);
    }

    #[test]
    fn weights_enumerate_elements_in_storage_order() {
        let m = material(vec![SlotKind::Kd, SlotKind::Basis(0)], false);
        let g = GroupMeta {
            material: 0,
            pixels: 1,
            slots: 2,
            active: vec![0, 1],
            row_len: 0,
            compressed_rank: None,
            scale: 1.0,
        };
        let coeff = [[2.0, 2.0, 2.0], [3.0, 5.0, 7.0]];
        for channels in [1usize, 3] {
            let w = group_weights(&g, &m, &coeff, 3, channels, [1.0; 3]);
            let len = row_len(2, 2, 3, channels);
            assert_eq!(w.len(), 3 * len);
            // T2[b0=1, j1=0, j2=1], blue channel: c[1] * c[0] * c[1].
            let e = element_index(
                2,
                2,
                channels,
                1,
                &[0, 1],
                if channels == 3 { 2 } else { 0 },
            );
            assert_eq!(w[2 * len + e], 7.0 * 2.0 * 7.0);
            // T0[b0=0], red.
            assert_eq!(w[element_index(2, 2, channels, 0, &[], 0)], 2.0);
        }
    }
}

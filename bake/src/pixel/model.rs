//! The bake's material model: every slot of a material evaluated at once, and sampling by a
//! density that does not depend on the editable coefficients, so one trace serves every
//! coefficient setting (docs/pixel.md, "One trace, all slots").

use glam::Vec3;
use prt_formats::basis::BrdfBasis;
use prt_formats::pixel::SlotKind;
use prt_formats::Family;

use crate::brdf::{cosine_hemisphere, reflect, BrdfParams, BrdfSample, Lobe};
use crate::integrator::{MaterialModel, Slots, Surface, MAX_SLOTS};
use crate::sampling::Draw;
use crate::scene::Scene;

use super::layout::SlotLayout;

/// Lobe parameters the sampling mixture of an editable family uses besides the material's
/// starting value: the sharpest lobe of the basis range and one in the middle, so that any
/// edit within the range has a sampling component near it.
fn mixture_params(family: Family, start: f32, basis: &BrdfBasis) -> [f32; 3] {
    let [lo, hi] = basis.param_range;
    if family.sharper_with_larger_param() {
        // Shininess: the sharpest lobe is at the top of the range.
        [start, hi, (lo.max(1.0) * hi).sqrt()]
    } else {
        // Roughness: the sharpest lobe is at the bottom of the range.
        [start, lo, (lo * hi).sqrt()]
    }
}

/// Mixture weights: cosine, starting lobe, sharpest lobe, middle lobe.
const MIXTURE: [f32; 4] = [0.4, 0.3, 0.15, 0.15];

/// Slot evaluation and coefficient-independent sampling for the bake (and for the
/// projected-BRDF reference, which must use the very same paths).
pub struct BakeModel<'a> {
    scene: &'a Scene,
    layout: &'a SlotLayout,
    /// Per material: the parameters of its sampling mixture (editable glossy only).
    mixtures: Vec<Option<(Family, [f32; 3])>>,
}

impl<'a> BakeModel<'a> {
    pub fn new(scene: &'a Scene, layout: &'a SlotLayout) -> Self {
        let mixtures = scene
            .materials
            .iter()
            .zip(&layout.materials)
            .map(|(m, meta)| {
                let basis = meta.basis.map(|b| &layout.bases[b as usize])?;
                let f = m.brdf.family;
                let p = m
                    .brdf
                    .param
                    .clamp(basis.param_range[0], basis.param_range[1]);
                Some((f, mixture_params(f, p, basis)))
            })
            .collect();
        BakeModel {
            scene,
            layout,
            mixtures,
        }
    }

    #[inline]
    fn texture(&self, s: &Surface) -> Option<Vec3> {
        let m = &self.scene.materials[s.material as usize];
        m.base_color_texture
            .and_then(|t| self.scene.textures.get(t))
            .map(|t| t.sample(s.uv))
    }

    /// The true BRDF of a fixed material at `s` (texture applied).
    #[inline]
    fn fixed_brdf(&self, s: &Surface) -> BrdfParams {
        let mut b = self.scene.materials[s.material as usize].brdf;
        if let Some(t) = self.texture(s) {
            b.kd *= t;
        }
        b
    }
}

impl MaterialModel for BakeModel<'_> {
    fn eval(&self, s: &Surface, _depth: usize, wo: Vec3, wi: Vec3, out: &mut Slots) {
        let meta = &self.layout.materials[s.material as usize];
        out.material = s.material;
        out.len = meta.slots.len();
        if wo.z <= 0.0 || wi.z <= 0.0 {
            out.values[..out.len].fill(Vec3::ZERO);
            return;
        }
        let mut basis_vals = [0.0f32; MAX_SLOTS];
        if let Some(b) = meta.basis {
            self.layout.bases[b as usize].eval_all_local(
                wi.to_array(),
                wo.to_array(),
                &mut basis_vals,
            );
        }
        let m = &self.scene.materials[s.material as usize];
        for (k, slot) in meta.slots.iter().enumerate() {
            out.values[k] = match *slot {
                SlotKind::Kd => self.texture(s).unwrap_or(Vec3::ONE) * std::f32::consts::FRAC_1_PI,
                SlotKind::Basis(b) => Vec3::splat(basis_vals[b as usize]),
                SlotKind::Lobe => Vec3::splat(m.brdf.family.specular_lobe(m.brdf.param, wo, wi)),
            };
        }
    }

    fn sample<D: Draw>(&self, s: &Surface, wo: Vec3, rng: &mut D) -> Option<BrdfSample> {
        let u_lobe = rng.next_f32();
        let u = rng.next_vec2();
        match self.mixtures[s.material as usize] {
            None => self.fixed_brdf(s).sample(wo, u, u_lobe),
            Some((family, params)) => {
                if wo.z <= 0.0 {
                    return None;
                }
                let mut acc = MIXTURE[0];
                let wi = if u_lobe < acc {
                    cosine_hemisphere(u)
                } else {
                    let mut k = 0;
                    for (i, w) in MIXTURE[1..].iter().enumerate() {
                        acc += w;
                        k = i;
                        if u_lobe < acc {
                            break;
                        }
                    }
                    let h = family.sample_half(params[k], u)?;
                    reflect(wo, h)
                };
                if wi.z <= 0.0 {
                    return None;
                }
                let pdf = self.pdf(s, wo, wi);
                (pdf > 0.0 && pdf.is_finite()).then_some(BrdfSample { wi, pdf })
            }
        }
    }

    fn pdf(&self, s: &Surface, wo: Vec3, wi: Vec3) -> f32 {
        match self.mixtures[s.material as usize] {
            None => self.fixed_brdf(s).pdf(wo, wi),
            Some((family, params)) => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let mut pdf = MIXTURE[0] * wi.z * std::f32::consts::FRAC_1_PI;
                for (w, p) in MIXTURE[1..].iter().zip(params) {
                    pdf += w * family.lobe_pdf(p, wo, wi);
                }
                pdf
            }
        }
    }
}

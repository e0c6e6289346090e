//! The bake's material model: every slot of a material evaluated at once, and sampling by a
//! density that does not depend on the editable coefficients, so one trace serves every
//! coefficient setting (docs/pixel.md, "One trace, all slots").

use glam::{Vec2, Vec3};
use prt_formats::basis::BrdfBasis;
use prt_formats::pixel::SlotKind;
use prt_formats::Family;

use crate::brdf::{cosine_hemisphere, reflect, BrdfParams, BrdfSample, Lobe};
use crate::integrator::{MaterialModel, Slots, Surface, MAX_SLOTS};
use crate::sampling::{pick_component, Draw};
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

/// The sampling density of an editable glossy material: `MIXTURE` of the cosine lobe and the
/// family's lobes at `params` (starting, sharpest, middle).
#[derive(Clone, Copy, Debug)]
struct Mixture {
    family: Family,
    params: [f32; 3],
}

impl Mixture {
    /// A direction from the mixture; `u.x` picks the component ([`pick_component`]).
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BrdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let (k, x) = pick_component(u.x, &MIXTURE);
        let u = Vec2::new(x, u.y);
        let wi = if k == 0 {
            cosine_hemisphere(u)
        } else {
            let h = self.family.sample_half(self.params[k - 1], u)?;
            reflect(wo, h)
        };
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then_some(BrdfSample { wi, pdf })
    }

    /// The solid-angle density of [`Mixture::sample`].
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let mut pdf = MIXTURE[0] * wi.z * std::f32::consts::FRAC_1_PI;
        for (w, &p) in MIXTURE[1..].iter().zip(&self.params) {
            pdf += w * self.family.lobe_pdf(p, wo, wi);
        }
        pdf
    }
}

/// Slot evaluation and coefficient-independent sampling for the bake (and for the
/// projected-BRDF reference, which must use the very same paths).
pub struct BakeModel<'a> {
    scene: &'a Scene,
    layout: &'a SlotLayout,
    /// Per material: the parameters of its sampling mixture (editable glossy only).
    mixtures: Vec<Option<Mixture>>,
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
                Some(Mixture {
                    family: f,
                    params: mixture_params(f, p, basis),
                })
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

    /// The true BRDF of a fixed material at `s` (textures applied).
    #[inline]
    fn fixed_brdf(&self, s: &Surface) -> BrdfParams {
        let m = s.material as usize;
        self.scene.brdf_at(m, self.scene.materials[m].brdf, s.uv)
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
                SlotKind::Own => self.fixed_brdf(s).eval(wo, wi),
            };
        }
    }

    fn sample<D: Draw>(&self, s: &Surface, wo: Vec3, rng: &mut D) -> Option<BrdfSample> {
        let u = rng.next_vec2();
        match &self.mixtures[s.material as usize] {
            None => self.fixed_brdf(s).sample(wo, u),
            Some(mixture) => mixture.sample(wo, u),
        }
    }

    fn pdf(&self, s: &Surface, wo: Vec3, wi: Vec3) -> f32 {
        match &self.mixtures[s.material as usize] {
            None => self.fixed_brdf(s).pdf(wo, wi),
            Some(mixture) => mixture.pdf(wo, wi),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;
    use std::f64::consts::PI;

    /// The mixture's samples follow its pdf: a histogram over cos(theta) of 400K samples
    /// against the pdf integrated over each bin (a fine midpoint rule over cos(theta) and
    /// phi), within 4 standard deviations plus 0.2 % of the samples (the rule's error next
    /// to the sharpest lobe's peak), for both families and three outgoing angles.
    #[test]
    fn mixture_samples_follow_its_pdf() {
        let mixtures = [
            Mixture {
                family: Family::Ggx,
                params: [0.12, 0.02, (0.02f32).sqrt()],
            },
            Mixture {
                family: Family::BlinnPhong,
                params: [20.0, 200.0, (200.0f32).sqrt()],
            },
        ];
        let (bins, sub, nphi) = (10usize, 200usize, 720usize);
        let n = 400_000usize;
        let mut rng = Rng::for_sample(21, 22, 23);
        for m in mixtures {
            for theta_o in [0.0f32, 40.0, 75.0] {
                let t = theta_o.to_radians();
                let wo = Vec3::new(t.sin(), 0.0, t.cos());
                let mut observed = vec![0.0f64; bins];
                for _ in 0..n {
                    if let Some(s) = m.sample(wo, rng.next_vec2()) {
                        let z = s.wi.z.clamp(0.0, 0.999_999) as f64;
                        observed[(z * bins as f64) as usize] += 1.0;
                    }
                }
                for (b, &obs) in observed.iter().enumerate() {
                    let mut mass = 0.0f64;
                    for i in 0..sub {
                        let z = (b as f64 + (i as f64 + 0.5) / sub as f64) / bins as f64;
                        let r = (1.0 - z * z).max(0.0).sqrt();
                        for k in 0..nphi {
                            let phi = 2.0 * PI * (k as f64 + 0.5) / nphi as f64;
                            let wi =
                                Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                            mass += m.pdf(wo, wi) as f64;
                        }
                    }
                    let dz_dphi = 2.0 * PI / (bins * sub * nphi) as f64;
                    let expected = mass * dz_dphi * n as f64;
                    let tol = 4.0 * expected.sqrt() + 0.002 * n as f64;
                    assert!(
                        (obs - expected).abs() < tol,
                        "{m:?} theta_o {theta_o}: cos bin {b}: {obs} samples, {expected:.0} expected"
                    );
                }
            }
        }
    }
}

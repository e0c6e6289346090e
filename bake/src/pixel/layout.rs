//! Which slots each material gets and where they sit globally: "model only what a scene needs"
//! (docs/pixel.md, "Allocation"). Also the coefficients of every slot for a parameter setting.

use glam::Vec3;
use prt_formats::basis::BrdfBasis;
use prt_formats::pixel::{slot_coefficients, MaterialMeta, MaterialParams, SlotKind};
use prt_formats::Family;

use crate::integrator::MAX_SLOTS;
use crate::scene::{Environment, PunctualLight, Scene};

use super::error::PixelError;

/// Which slots each material has, where they sit globally, and the bases they use.
#[derive(Clone, Debug)]
pub struct SlotLayout {
    pub materials: Vec<MaterialMeta>,
    pub bases: Vec<BrdfBasis>,
    /// Total number of global slots J.
    pub total_slots: usize,
    /// 1 when every tensor value is gray (colours live in coefficients), else 3.
    pub channels: usize,
    /// The lights' common colour, divided out of gray tensors (ONE for RGB tensors).
    pub tint: Vec3,
    /// Why each material got the slots it has (for the allocation report).
    pub reasons: Vec<String>,
}

/// The colour all non-black `colours` share up to a scale (normalised to a maximum component
/// of 1), or None when they differ. White when there is no light at all.
fn common_chromaticity(colours: &[Vec3]) -> Option<Vec3> {
    let mut common: Option<Vec3> = None;
    for &c in colours {
        let m = c.max_element();
        if m.is_nan() || m <= 0.0 {
            continue;
        }
        let k = c / m;
        match common {
            None => common = Some(k),
            Some(x) if (x - k).abs().max_element() <= 1e-5 => {}
            Some(_) => return None,
        }
    }
    Some(common.unwrap_or(Vec3::ONE))
}

/// The slot allocation of a scene before its bases are built: enough to size the bake (the
/// memory estimate and `--max-memory` come before the expensive basis build).
#[derive(Clone, Debug)]
pub struct SlotPlan {
    pub materials: Vec<MaterialMeta>,
    /// The basis each `MaterialMeta::basis` index names: its family and size.
    pub basis_families: Vec<(Family, usize)>,
    pub total_slots: usize,
    pub channels: usize,
    pub tint: Vec3,
    pub reasons: Vec<String>,
}

impl SlotLayout {
    /// Slots per material: editable glossy materials get their family's basis (which must be
    /// in `bases`), editable diffuse ones a single Kd slot, fixed ones a Kd slot and/or a lobe
    /// slot (none for a black material). A material with a diffuse texture keeps Kd as its own
    /// slot (the texture is baked into it); otherwise Kd folds into basis 0.
    pub fn new(scene: &Scene, bases: &[BrdfBasis]) -> Result<SlotLayout, PixelError> {
        let counts: Vec<(Family, usize)> = bases.iter().map(|b| (b.family, b.num_bases)).collect();
        SlotPlan::new(scene, &counts)?.with_bases(bases)
    }
}

/// The slots of every material, before the tensors' channel count is chosen.
struct MaterialSlots {
    materials: Vec<MaterialMeta>,
    basis_families: Vec<(Family, usize)>,
    total_slots: usize,
    reasons: Vec<String>,
}

/// Whether a base-colour texture, or a BRDF varying over a surface ([`SlotKind::Own`]),
/// colours a slot (then tensors must be RGB).
fn textured_slots(materials: &[MaterialMeta]) -> bool {
    materials
        .iter()
        .any(|m| (m.textured && !m.slots.is_empty()) || m.slots.contains(&SlotKind::Own))
}

/// Slots per material (see [`SlotLayout::new`]) and why each material got them.
fn material_slots(scene: &Scene, counts: &[(Family, usize)]) -> Result<MaterialSlots, PixelError> {
    let mut materials = Vec::with_capacity(scene.materials.len());
    let mut used_bases: Vec<(Family, usize)> = Vec::new();
    let mut reasons = Vec::new();
    let mut offset = 0u32;
    for m in &scene.materials {
        let b = &m.brdf;
        let textured = m.base_color_texture.is_some();
        let mut basis_index = None;
        let (slots, reason) = if m.editable && b.family != Family::Diffuse {
            let Some(&(family, num_bases)) = counts.iter().find(|x| x.0 == b.family) else {
                return Err(PixelError::MissingBasis {
                    material: m.name.clone(),
                    family: b.family,
                });
            };
            let idx = match used_bases.iter().position(|x| x.0 == family) {
                Some(i) => i,
                None => {
                    used_bases.push((family, num_bases));
                    used_bases.len() - 1
                }
            };
            basis_index = Some(idx as u32);
            let mut s = Vec::new();
            if textured {
                s.push(SlotKind::Kd);
            }
            s.extend((0..num_bases as u32).map(SlotKind::Basis));
            let why = format!(
                "editable {}: {} basis BRDFs{}",
                b.family.name(),
                num_bases,
                if textured {
                    " + a textured Kd slot"
                } else {
                    ""
                }
            );
            (s, why)
        } else if m.editable {
            (
                vec![SlotKind::Kd],
                "editable diffuse: 1 slot (Kd)".to_string(),
            )
        } else if m.metallic_roughness.is_some() {
            (
                vec![SlotKind::Own],
                "fixed, its parameters varying over its surface (metallicRoughnessTexture): \
                 1 slot (its own BRDF, RGB)"
                    .to_string(),
            )
        } else {
            let mut s = Vec::new();
            if b.kd != Vec3::ZERO {
                s.push(SlotKind::Kd);
            }
            if b.family != Family::Diffuse && b.ks != Vec3::ZERO {
                s.push(SlotKind::Lobe);
            }
            let why = match s.len() {
                0 => "fixed, black: no slot (reflects nothing)".to_string(),
                1 => "fixed: 1 slot".to_string(),
                _ => "fixed glossy: 2 slots (Kd, lobe)".to_string(),
            };
            (s, why)
        };
        if slots.len() > MAX_SLOTS {
            return Err(PixelError::TooManySlots {
                material: m.name.clone(),
                slots: slots.len(),
                max: MAX_SLOTS,
            });
        }
        reasons.push(format!("{}: {}", m.name, reason));
        materials.push(MaterialMeta {
            name: m.name.clone(),
            editable: m.editable,
            family: b.family,
            kd: b.kd.to_array(),
            ks: b.ks.to_array(),
            param: b.param,
            textured,
            slot_offset: offset,
            basis: basis_index,
            slots,
        });
        offset += materials.last().map_or(0, |m| m.slots.len() as u32);
    }
    Ok(MaterialSlots {
        materials,
        basis_families: used_bases,
        total_slots: offset as usize,
        reasons,
    })
}

impl SlotPlan {
    /// As [`SlotLayout::new`], from the number of basis BRDFs each family will get.
    pub fn new(scene: &Scene, counts: &[(Family, usize)]) -> Result<SlotPlan, PixelError> {
        let MaterialSlots {
            materials,
            basis_families,
            total_slots,
            mut reasons,
        } = material_slots(scene, counts)?;
        // Gray tensors when every light has one chromaticity (factored out as `tint`, which
        // the runtime multiplies back in) and no texture colours a slot; RGB otherwise.
        let mut colours: Vec<Vec3> = Vec::new();
        let mut emissive_texture = false;
        for m in &scene.materials {
            if m.is_emissive() {
                colours.push(m.emission);
                emissive_texture |= m.emissive_texture.is_some();
            }
        }
        for l in &scene.lights {
            colours.push(match *l {
                PunctualLight::Point { intensity, .. } | PunctualLight::Spot { intensity, .. } => {
                    intensity
                }
                PunctualLight::Directional { irradiance, .. } => irradiance,
            });
        }
        match &scene.environment {
            Environment::Constant(c) => colours.push(*c),
            Environment::LatLong { texels, .. } => colours.extend(texels.iter().copied()),
        }
        let tint = common_chromaticity(&colours);
        let textured = textured_slots(&materials);
        let single_tint = tint.is_some() && !emissive_texture;
        let channels = if single_tint && !textured { 1 } else { 3 };
        let tint = if channels == 1 {
            tint.unwrap_or(Vec3::ONE)
        } else {
            Vec3::ONE
        };
        reasons.push(format!(
            "tensors: {} ({})",
            if channels == 1 {
                "gray (1 channel)"
            } else {
                "RGB (3 channels)"
            },
            if channels == 1 {
                "one light colour, factored out; no textures: colours live in the coefficients"
            } else if !single_tint {
                "lights of different colours"
            } else {
                "a diffuse texture is baked into slots"
            }
        ));
        Ok(SlotPlan {
            total_slots,
            materials,
            basis_families,
            channels,
            tint,
            reasons,
        })
    }

    /// The slots of [`SlotPlan::new`] for tensors that are **per unit radiance** (the
    /// per-vertex mode: the light is a runtime input, so there is no light colour to factor
    /// out and `tint` is white): gray unless a base-colour texture colours a slot.
    pub fn per_unit_radiance(
        scene: &Scene,
        counts: &[(Family, usize)],
    ) -> Result<SlotPlan, PixelError> {
        let MaterialSlots {
            materials,
            basis_families,
            total_slots,
            mut reasons,
        } = material_slots(scene, counts)?;
        let channels = if textured_slots(&materials) { 3 } else { 1 };
        reasons.push(format!(
            "tensors: {}",
            if channels == 1 {
                "gray (1 channel): per unit radiance, colours live in the coefficients and the light"
            } else {
                "RGB (3 channels): a diffuse texture or a varying BRDF is baked into slots"
            }
        ));
        Ok(SlotPlan {
            materials,
            basis_families,
            total_slots,
            channels,
            tint: Vec3::ONE,
            reasons,
        })
    }

    /// The layout with its bases: one per planned family, of the planned size.
    pub fn with_bases(self, bases: &[BrdfBasis]) -> Result<SlotLayout, PixelError> {
        let mut used = Vec::with_capacity(self.basis_families.len());
        for &(family, num_bases) in &self.basis_families {
            let Some(basis) = bases.iter().find(|b| b.family == family) else {
                let material = self
                    .materials
                    .iter()
                    .find(|m| m.editable && m.family == family)
                    .map_or_else(String::new, |m| m.name.clone());
                return Err(PixelError::MissingBasis { material, family });
            };
            if basis.num_bases != num_bases {
                return Err(PixelError::BasisSize {
                    family,
                    planned: num_bases,
                    built: basis.num_bases,
                });
            }
            used.push(basis.clone());
        }
        Ok(SlotLayout {
            materials: self.materials,
            bases: used,
            total_slots: self.total_slots,
            channels: self.channels,
            tint: self.tint,
            reasons: self.reasons,
        })
    }
}

impl SlotLayout {
    /// RGB coefficient of every global slot for the materials' baked (starting) parameters,
    /// with `overrides` replacing some materials' parameters.
    pub fn coefficients(&self, overrides: &[(usize, MaterialParams)]) -> Vec<[f32; 3]> {
        let mut out = Vec::with_capacity(self.total_slots);
        for (i, m) in self.materials.iter().enumerate() {
            let p = overrides
                .iter()
                .rev()
                .find(|(k, _)| *k == i)
                .map_or(m.params(), |(_, p)| *p);
            let lobe = match m.basis {
                Some(b) => self.bases[b as usize].coefficients(p.param).0,
                None => Vec::new(),
            };
            out.extend(slot_coefficients(m, &p, &lobe));
        }
        out
    }

    /// The same coefficients per material, as the reference renderer's contraction wants.
    pub fn coefficients_per_material(
        &self,
        overrides: &[(usize, MaterialParams)],
    ) -> Vec<Vec<Vec3>> {
        let flat = self.coefficients(overrides);
        self.materials
            .iter()
            .map(|m| {
                let o = m.slot_offset as usize;
                flat[o..o + m.slots.len()]
                    .iter()
                    .map(|c| Vec3::from_array(*c))
                    .collect()
            })
            .collect()
    }
}

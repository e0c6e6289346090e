//! Materials: one per glTF material (plus `default`), and the mapping of glTF
//! metallic-roughness values to our BRDF families with the config's overrides
//! ([`resolve_brdf`]; the rules are in docs/conventions.md, "Materials").

use std::collections::HashMap;

use glam::Vec3;

use super::texture::Encoding;
use super::Loader;
use crate::brdf::{BrdfParams, Family, ALPHA_RANGE, SHININESS_RANGE};
use crate::config::MaterialConfig;
use crate::config::Mode;
use crate::scene::error::BrdfConfigError;
use crate::scene::error::MaterialError;
use crate::scene::{Material, MetallicRoughnessMap, SceneError};

/// Name given to the material of primitives that have none.
pub const DEFAULT_MATERIAL_NAME: &str = "default";

/// Ks used when the config switches a material to a specular family and neither it nor the
/// glTF gives one: glTF's dielectric F0.
pub const DEFAULT_KS: f32 = 0.04;

impl Loader<'_> {
    /// One [`Material`] per glTF material (plus `default` when a primitive has none), with the
    /// config's overrides applied.
    pub(super) fn materials(&mut self, uses_default: bool) -> Result<Vec<Material>, SceneError> {
        let doc = self.doc;
        let mut names: Vec<String> = Vec::new();
        let mut seen: HashMap<String, usize> = HashMap::new();
        for m in doc.materials() {
            let i = m.index().unwrap_or(names.len());
            let mut name = m
                .name()
                .map(str::to_owned)
                .unwrap_or_else(|| format!("material{i}"));
            if seen.contains_key(&name) {
                // Config tables are keyed by name, so names must be unique.
                let unique = format!("{name}#{i}");
                self.warnings.push(format!(
                    "{}: material {i} is named \"{name}\" like material {}; it is called \
                     \"{unique}\" here",
                    self.path.display(),
                    seen[&name]
                ));
                name = unique;
            }
            seen.insert(name.clone(), i);
            names.push(name);
        }
        if uses_default {
            let mut name = DEFAULT_MATERIAL_NAME.to_owned();
            if seen.contains_key(&name) {
                name = format!("{DEFAULT_MATERIAL_NAME}#{}", names.len());
            }
            names.push(name);
        }

        // Every config table must name a material of the scene.
        for (name, _) in &self.config.materials {
            if !names.iter().any(|n| n == name) {
                return Err(SceneError::UnknownMaterial {
                    config: self.config.config_path.clone(),
                    scene: self.path.to_path_buf(),
                    name: name.clone(),
                    available: names.iter().map(|n| format!("\"{n}\"")).collect(),
                });
            }
        }

        let mut out = Vec::with_capacity(names.len());
        for (i, m) in doc.materials().enumerate() {
            let name = names[i].clone();
            let merr = |source: MaterialError| SceneError::Material {
                path: self.path.to_path_buf(),
                material: name.clone(),
                source: Box::new(source),
            };
            let pbr = m.pbr_metallic_roughness();
            let bc = pbr.base_color_factor();
            let base = Vec3::new(bc[0], bc[1], bc[2]);
            if !base.is_finite() || base.min_element() < 0.0 {
                return Err(merr(MaterialError::BaseColor(bc)));
            }
            let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
            if !metallic.is_finite() || !roughness.is_finite() {
                return Err(merr(MaterialError::Factors));
            }
            let strength = m.emissive_strength().unwrap_or(1.0);
            let emission = Vec3::from_array(m.emissive_factor()) * strength;
            if !emission.is_finite() || emission.min_element() < 0.0 {
                return Err(merr(MaterialError::Emission(emission)));
            }
            let base_color_texture = match pbr.base_color_texture() {
                Some(info) => Some(self.texture(
                    info.texture(),
                    info.tex_coord(),
                    Encoding::Srgb,
                    &name,
                    "baseColorTexture",
                )?),
                None => None,
            };
            let emissive_texture = match m.emissive_texture() {
                Some(info) => Some(self.texture(
                    info.texture(),
                    info.tex_coord(),
                    Encoding::Srgb,
                    &name,
                    "emissiveTexture",
                )?),
                None => None,
            };
            let normal_texture = match m.normal_texture() {
                Some(info) => {
                    let scale = info.scale();
                    if !scale.is_finite() {
                        return Err(merr(MaterialError::NormalScale(scale)));
                    }
                    Some(self.texture(
                        info.texture(),
                        info.tex_coord(),
                        Encoding::Normal { scale },
                        &name,
                        "normalTexture",
                    )?)
                }
                None => None,
            };
            let gltf_pbr = GltfPbr {
                base,
                metallic,
                roughness,
            };
            let cfg = self.config.material(&name);
            let (metallic_roughness, described) = match pbr.metallic_roughness_texture() {
                Some(info) => self.metallic_roughness(&name, cfg, info, gltf_pbr)?,
                None => (None, gltf_pbr),
            };
            let brdf = resolve_brdf(Some(described), cfg).map_err(|e| SceneError::Material {
                path: self.config.config_path.clone(),
                material: name.clone(),
                source: Box::new(e.into()),
            })?;
            self.check_reflectance(&name, cfg, &brdf);
            out.push(Material {
                name,
                brdf,
                base_color_texture,
                normal_texture,
                metallic_roughness,
                emission,
                emissive_texture,
                editable: cfg.is_some_and(|c| c.editable),
            });
        }
        if uses_default {
            let name = names[names.len() - 1].clone();
            let cfg = self.config.material(&name);
            let brdf = resolve_brdf(None, cfg).map_err(|e| SceneError::Material {
                path: self.config.config_path.clone(),
                material: name.clone(),
                source: Box::new(e.into()),
            })?;
            self.check_reflectance(&name, cfg, &brdf);
            out.push(Material {
                name,
                brdf,
                base_color_texture: None,
                normal_texture: None,
                metallic_roughness: None,
                emission: Vec3::ZERO,
                emissive_texture: None,
                editable: cfg.is_some_and(|c| c.editable),
            });
        }
        Ok(out)
    }

    /// The metallicRoughnessTexture of material `name`: the glTF values one BRDF for the whole
    /// material maps from (the factors scaled by the texture's mean: the factors alone are
    /// often placeholders, (1, 1), that the texture scales down), and the map itself where
    /// the BRDF may vary over the surface: a fixed material whose BRDF the config leaves as
    /// the glTF made it. Elsewhere the variation is dropped, with a warning that says why
    /// (docs/conventions.md, "glTF textures in each mode").
    fn metallic_roughness(
        &mut self,
        name: &str,
        cfg: Option<&MaterialConfig>,
        info: gltf::texture::Info,
        pbr: GltfPbr,
    ) -> Result<(Option<MetallicRoughnessMap>, GltfPbr), SceneError> {
        let texture = self.texture(
            info.texture(),
            info.tex_coord(),
            Encoding::Linear,
            name,
            "metallicRoughnessTexture",
        )?;
        let map = MetallicRoughnessMap { texture, pbr };
        let mean = map.mean_pbr(&self.textures[texture]);
        let family = |p: GltfPbr| BrdfParams::from_gltf_pbr(p.base, p.metallic, p.roughness).family;
        let means = format!(
            "the texture's mean (metallic {:.2}, roughness {:.2})",
            mean.metallic, mean.roughness
        );
        let why_not = match cfg {
            Some(c) if c.editable => Some(format!(
                "an editable material has one set of parameters, the ones you edit; they start \
                 at {means}. To bake the texture's variation instead, make it fixed \
                 (`editable = false` in `[materials.{name}]` of the bake config)"
            )),
            // A `family` equal to the glTF's mapping (as `--print-config` writes it) changes
            // nothing.
            Some(c)
                if c.family
                    .is_some_and(|f| f != family(pbr) && f != family(mean))
                    || c.kd.is_some()
                    || c.ks.is_some()
                    || c.alpha.is_some()
                    || c.shininess.is_some() =>
            {
                Some("the config sets the material's BRDF".to_owned())
            }
            _ => None,
        };
        if let Some(why) = why_not {
            self.warnings.push(format!(
                "{}: material \"{name}\": metallicRoughnessTexture's variation is not baked: \
                 {why}",
                self.path.display()
            ));
            return Ok((None, mean));
        }
        if self.config.mode == Mode::Vertex {
            self.warnings.push(format!(
                "{}: material \"{name}\": metallicRoughnessTexture is used where light reflects \
                 off it before reaching another surface; its last reflection towards the eye, \
                 evaluated at run time in the per-vertex mode, uses one BRDF for the whole \
                 material, {means}",
                self.path.display(),
            ));
        }
        Ok((Some(map), mean))
    }

    /// Warns when the config's `kd` or `ks` makes material `name` reflect more light than it
    /// receives ([`prt_formats::family::reflectance_warning`]). Values mapped from the glTF
    /// alone are not checked: glTF's model weighs its diffuse and specular terms by Fresnel, and
    /// our sum of the two exceeds 1 for white dielectrics the author made correctly.
    fn check_reflectance(&mut self, name: &str, cfg: Option<&MaterialConfig>, brdf: &BrdfParams) {
        if !cfg.is_some_and(|c| c.kd.is_some() || c.ks.is_some()) {
            return;
        }
        let warning = prt_formats::family::reflectance_warning(
            name,
            brdf.family,
            brdf.kd.to_array(),
            brdf.ks.to_array(),
        );
        if let Some(w) = warning {
            self.warnings.push(format!(
                "bake config {}: `materials.{name}`: {w}",
                self.config.config_path.display()
            ));
        }
    }
}

/// The metallic-roughness values of a glTF material.
#[derive(Clone, Copy, Debug)]
pub struct GltfPbr {
    pub base: Vec3,
    pub metallic: f32,
    pub roughness: f32,
}

/// Blinn-Phong exponent with the same lobe width as a GGX/Beckmann alpha (Walter et al. 2007,
/// "Microfacet models for refraction", eq. 29: s = 2 / alpha^2 - 2), clamped to the accepted
/// range.
pub fn alpha_to_shininess(alpha: f32) -> f32 {
    let a = alpha.max(ALPHA_RANGE.0);
    (2.0 / (a * a) - 2.0).clamp(SHININESS_RANGE.0, SHININESS_RANGE.1)
}

/// The BRDF of one material: the glTF mapping (`pbr`; `None` for the default material, white
/// diffuse) with the config's overrides. Rules (docs/conventions.md):
///
/// - `family` defaults to the glTF mapping's ([`BrdfParams::from_gltf_pbr`]).
/// - `kd` defaults to the glTF Kd = baseColor (1 - metallic).
/// - `ks` defaults to the glTF Ks = mix(0.04, baseColor, metallic) and the lobe parameter to the
///   glTF roughness (GGX alpha = roughness^2; Blinn-Phong s = 2 / alpha^2 - 2) — but only when
///   the glTF mapping itself is specular. A fully rough dielectric (mapped to `diffuse`) or the
///   default material supplies no specular lobe: for an *editable* material that is an error
///   (the user must say which lobe the bake starts from); otherwise the fallbacks are
///   Ks = 0.04 and the glTF roughness as above.
/// - A parameter the resolved family does not use is an error.
pub fn resolve_brdf(
    pbr: Option<GltfPbr>,
    cfg: Option<&MaterialConfig>,
) -> Result<BrdfParams, BrdfConfigError> {
    let gltf = match pbr {
        Some(p) => BrdfParams::from_gltf_pbr(p.base, p.metallic, p.roughness),
        None => BrdfParams::diffuse(Vec3::ONE),
    };
    let Some(cfg) = cfg else {
        return Ok(gltf);
    };
    let family = cfg.family.unwrap_or(gltf.family);
    let stray = |key: &'static str| {
        Err(BrdfConfigError::StrayParameter {
            key,
            family,
            family_from_gltf: cfg.family.is_none(),
        })
    };
    match family {
        Family::Diffuse => {
            if cfg.ks.is_some() {
                return stray("ks");
            }
            if cfg.alpha.is_some() {
                return stray("alpha");
            }
            if cfg.shininess.is_some() {
                return stray("shininess");
            }
        }
        Family::BlinnPhong => {
            if cfg.alpha.is_some() {
                return stray("alpha");
            }
        }
        Family::Ggx => {
            if cfg.shininess.is_some() {
                return stray("shininess");
            }
        }
    }

    let kd = cfg.kd.unwrap_or(gltf.kd);
    if family == Family::Diffuse {
        return Ok(BrdfParams::diffuse(kd));
    }
    let gltf_specular = gltf.family != Family::Diffuse;
    let roughness = pbr.map_or(1.0, |p| p.roughness.clamp(0.0, 1.0));
    let fallback_alpha = (roughness * roughness).clamp(ALPHA_RANGE.0, ALPHA_RANGE.1);
    let fallback_ks = pbr.map_or(Vec3::splat(DEFAULT_KS), |p| {
        Vec3::splat(DEFAULT_KS).lerp(p.base, p.metallic.clamp(0.0, 1.0))
    });
    let (param_key, cfg_param) = match family {
        Family::BlinnPhong => ("shininess", cfg.shininess),
        _ => ("alpha", cfg.alpha),
    };
    if !gltf_specular && cfg.editable {
        let mut missing = Vec::new();
        if cfg.ks.is_none() {
            missing.push("ks");
        }
        if cfg_param.is_none() {
            missing.push(param_key);
        }
        if !missing.is_empty() {
            return Err(BrdfConfigError::MissingSpecular {
                family,
                missing,
                default_material: pbr.is_none(),
            });
        }
    }
    let ks = cfg
        .ks
        .unwrap_or(if gltf_specular { gltf.ks } else { fallback_ks });
    let gltf_alpha = if gltf_specular {
        gltf.param
    } else {
        fallback_alpha
    };
    let param = match family {
        Family::BlinnPhong => cfg
            .shininess
            .unwrap_or_else(|| alpha_to_shininess(gltf_alpha)),
        _ => cfg.alpha.unwrap_or(gltf_alpha),
    };
    Ok(BrdfParams {
        family,
        kd,
        ks,
        param,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> MaterialConfig {
        MaterialConfig::default()
    }

    #[test]
    fn overrides_apply_individually() {
        let metal = GltfPbr {
            base: Vec3::new(0.9, 0.6, 0.2),
            metallic: 1.0,
            roughness: 0.5,
        };
        let g = resolve_brdf(Some(metal), None).unwrap();
        assert_eq!(g.family, Family::Ggx);
        let c = MaterialConfig {
            alpha: Some(0.1),
            ..cfg()
        };
        let b = resolve_brdf(Some(metal), Some(&c)).unwrap();
        assert_eq!((b.family, b.ks, b.param), (Family::Ggx, g.ks, 0.1));
        let c = MaterialConfig {
            family: Some(Family::BlinnPhong),
            ..cfg()
        };
        let b = resolve_brdf(Some(metal), Some(&c)).unwrap();
        assert_eq!(b.family, Family::BlinnPhong);
        assert!((b.param - alpha_to_shininess(0.25)).abs() < 1e-3);
        assert_eq!(b.ks, g.ks);
    }

    #[test]
    fn editable_specular_needs_params_when_gltf_is_diffuse() {
        let rough = GltfPbr {
            base: Vec3::splat(0.5),
            metallic: 0.0,
            roughness: 1.0,
        };
        let c = MaterialConfig {
            editable: true,
            family: Some(Family::BlinnPhong),
            ..cfg()
        };
        let e = resolve_brdf(Some(rough), Some(&c)).unwrap_err().to_string();
        assert!(e.contains("`ks`") && e.contains("`shininess`"), "{e}");
        let c = MaterialConfig {
            editable: false,
            ..c
        };
        let b = resolve_brdf(Some(rough), Some(&c)).unwrap();
        assert_eq!(b.ks, Vec3::splat(DEFAULT_KS));
        let c = MaterialConfig {
            alpha: Some(0.3),
            ..cfg()
        };
        assert!(matches!(
            resolve_brdf(Some(rough), Some(&c)),
            Err(BrdfConfigError::StrayParameter { key: "alpha", .. })
        ));
    }
}

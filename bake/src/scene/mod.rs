//! The in-memory scene every part of the baker works on: world-space triangles grouped by
//! material ("objects" in the thesis' sense: one editable BRDF per material), lights, camera,
//! environment. Produced by [`load`] from a glTF file plus the bake config ([`gltf`]).
//!
//! Conventions (see docs/conventions.md): right-handed, +Y up, metres; linear RGB radiance;
//! glTF punctual light intensities are taken as radiometric (1 cd == 1 W/sr per channel unit).

use glam::{Vec2, Vec3};

use crate::brdf::BrdfParams;

pub mod envmap;
pub mod error;
pub mod gltf;

pub use error::{BrdfConfigError, SceneError};
pub use gltf::camera::framing_camera;
pub use gltf::material::{
    alpha_to_shininess, resolve_brdf, GltfPbr, DEFAULT_KS, DEFAULT_MATERIAL_NAME,
};
pub use gltf::texture::srgb_to_linear;
pub use gltf::{load, load_with_warnings, unlit_warning};

/// A texture: linear RGB (sRGB-encoded glTF base-colour/emissive textures are decoded on
/// load), or a normal map's tangent-space vectors (decoded on load with the map's scale,
/// [`prt_formats::normal_map::decode_texel`]).
#[derive(Clone, Debug)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first (glTF UV (0,0) is the top-left corner).
    pub texels: Vec<Vec3>,
}

impl Texture {
    /// Bilinear lookup with repeat wrapping ([`prt_formats::texture::sample_bilinear`], the
    /// lookup the per-vertex runtime uses too).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        Vec3::from_array(prt_formats::texture::sample_bilinear_by(
            self.width as usize,
            self.height as usize,
            uv.to_array(),
            |i| self.texels[i].to_array(),
        ))
    }
}

/// One material of the scene. Its index is the "object" index R of the transfer tensors.
#[derive(Clone, Debug)]
pub struct Material {
    /// The glTF material name (unnamed materials get `material<index>`).
    pub name: String,
    /// The BRDF the scene is rendered with (config overrides, else mapped from glTF PBR).
    pub brdf: BrdfParams,
    /// Index into [`Scene::textures`]; modulates the diffuse term (Kd) only.
    pub base_color_texture: Option<usize>,
    /// Index into [`Scene::textures`] of its normal map (decoded tangent-space vectors), which
    /// bends the shading normal wherever the material is shaded ([`Scene::bent_normal`]).
    pub normal_texture: Option<usize>,
    /// Its glTF metallicRoughnessTexture with the factors it scales, for a fixed material the
    /// config leaves as the glTF made it: the BRDF then varies over the surface
    /// ([`Scene::brdf_at`]). `None` for editable materials (their parameters are the user's).
    pub metallic_roughness: Option<MetallicRoughnessMap>,
    /// Emitted radiance (emissiveFactor x KHR_materials_emissive_strength), linear RGB.
    pub emission: Vec3,
    /// Index into [`Scene::textures`]; modulates `emission`.
    pub emissive_texture: Option<usize>,
    /// Editable in the bake (from the config).
    pub editable: bool,
}

/// A glTF metallicRoughnessTexture: per point, roughness = `pbr.roughness` x G and metallic =
/// `pbr.metallic` x B (linear texels), mapped to a BRDF like the factors alone
/// ([`BrdfParams::from_gltf_pbr`]).
#[derive(Clone, Copy, Debug)]
pub struct MetallicRoughnessMap {
    /// Index into [`Scene::textures`] (linear RGB texels).
    pub texture: usize,
    /// The material's base colour and factors.
    pub pbr: GltfPbr,
}

impl MetallicRoughnessMap {
    /// The factors scaled by the mean of `texture`'s texels (this map's texture): what one
    /// BRDF for the whole material uses.
    pub fn mean_pbr(&self, texture: &Texture) -> GltfPbr {
        let n = texture.texels.len().max(1) as f64;
        let (g, b) = texture.texels.iter().fold((0.0f64, 0.0f64), |(g, b), t| {
            (g + f64::from(t.y), b + f64::from(t.z))
        });
        GltfPbr {
            base: self.pbr.base,
            metallic: self.pbr.metallic * (b / n) as f32,
            roughness: self.pbr.roughness * (g / n) as f32,
        }
    }
}

impl Material {
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualLight {
    /// Radiant intensity (W/sr per channel) at `position`.
    Point { position: Vec3, intensity: Vec3 },
    /// Like a point light, restricted to a cone about `direction` (unit, the way light travels),
    /// with glTF's smooth falloff between the inner and outer cone angles (radians).
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        inner_cone: f32,
        outer_cone: f32,
    },
    /// Irradiance (W/m^2 per channel) on a surface facing the light; `direction` is unit, the
    /// way light travels.
    Directional { direction: Vec3, irradiance: Vec3 },
}

/// A pinhole perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    /// Unit vectors of the camera frame in world space (glTF cameras look down their local -Z).
    pub forward: Vec3,
    pub up: Vec3,
    pub right: Vec3,
    /// Vertical field of view, radians.
    pub yfov: f32,
}

/// Distant lighting reaching every point not occluded in a direction.
#[derive(Clone, Debug)]
pub enum Environment {
    /// Constant radiance from every direction (black = no environment).
    Constant(Vec3),
    /// Equirectangular (lat-long) radiance map, already multiplied by the config's intensity,
    /// row-major, top row first, in the convention of [`prt_formats::latlong`]: row 0 looks
    /// up (+Y), the centre column down -Z, u = 0.75 along +X.
    LatLong {
        width: u32,
        height: u32,
        texels: Vec<Vec3>,
    },
}

#[derive(Clone, Debug)]
pub struct Scene {
    /// World-space vertex positions, normals (unit) and UVs, one entry per vertex.
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    /// Indexed triangles into the vertex arrays; every triangle here is valid (finite,
    /// non-degenerate).
    pub triangles: Vec<[u32; 3]>,
    /// Material (object) index per triangle.
    pub triangle_material: Vec<u32>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub lights: Vec<PunctualLight>,
    pub camera: Camera,
    pub environment: Environment,
    /// Rotation of a lat-long environment about +Y, degrees (right-hand rule: +90 turns what
    /// was seen towards -Z to be seen towards -X; docs/conventions.md). The radiance arriving
    /// from direction d is the map's value at `R_y(-rotation) d`.
    pub environment_rotation: f32,
    /// Triangles dropped on load because they were degenerate, non-finite or beyond +-1e15 m.
    pub skipped_triangles: usize,
}

impl Scene {
    /// The BRDF of material `material` at texture coordinate `uv`: `brdf` (the material's, or
    /// a projection of it) with the base-colour texture multiplying Kd, or, for a material
    /// with a metallicRoughnessTexture, the BRDF its texels give there.
    #[inline]
    pub fn brdf_at(&self, material: usize, brdf: BrdfParams, uv: Vec2) -> BrdfParams {
        let m = &self.materials[material];
        let mut b = match m
            .metallic_roughness
            .and_then(|mr| Some((mr.pbr, self.textures.get(mr.texture)?)))
        {
            Some((pbr, t)) => {
                // Bilinear weights sum to 1 only up to rounding: a texel of exactly 1 (a fully
                // rough dielectric, mapped to `diffuse`) must not come back as 0.99999994 and
                // turn into a GGX lobe.
                let snap = |c: f32| if c > 1.0 - 1e-6 { 1.0 } else { c.max(0.0) };
                let texel = t.sample(uv);
                BrdfParams::from_gltf_pbr(
                    pbr.base,
                    pbr.metallic * snap(texel.z),
                    pbr.roughness * snap(texel.y),
                )
            }
            None => brdf,
        };
        if let Some(t) = m.base_color_texture.and_then(|t| self.textures.get(t)) {
            b.kd *= t.sample(uv);
        }
        b
    }

    /// The shading normal at texture coordinate `uv` of `triangle` for its unit interpolated
    /// normal `ns`: bent by its material's normal map where it has one
    /// ([`prt_formats::normal_map::perturb`]), else `ns`.
    pub fn bent_normal(&self, triangle: u32, uv: Vec2, ns: Vec3) -> Vec3 {
        let material = self.triangle_material[triangle as usize] as usize;
        let Some(map) = self.materials[material]
            .normal_texture
            .and_then(|t| self.textures.get(t))
        else {
            return ns;
        };
        let tri = self.triangles[triangle as usize];
        let p = tri.map(|i| self.positions[i as usize].to_array());
        let uvs = tri.map(|i| self.uvs[i as usize].to_array());
        let Some(axes) = prt_formats::normal_map::triangle_uv_axes(p, uvs) else {
            return ns;
        };
        Vec3::from_array(prt_formats::normal_map::perturb(
            ns.to_array(),
            axes,
            map.sample(uv).to_array(),
        ))
    }

    pub fn material_index(&self, name: &str) -> Option<usize> {
        self.materials.iter().position(|m| m.name == name)
    }

    /// Whether anything lights the scene: a material that emits on some triangle, a punctual
    /// light of non-zero intensity, or an environment that is not black everywhere.
    pub fn has_light(&self) -> bool {
        let emitting: Vec<bool> = self.materials.iter().map(Material::is_emissive).collect();
        let emitter = self
            .triangle_material
            .iter()
            .any(|&m| emitting.get(m as usize).copied().unwrap_or(false));
        let light = self.lights.iter().any(|l| match *l {
            PunctualLight::Point { intensity, .. } | PunctualLight::Spot { intensity, .. } => {
                intensity.max_element() > 0.0
            }
            PunctualLight::Directional { irradiance, .. } => irradiance.max_element() > 0.0,
        });
        let environment = match &self.environment {
            Environment::Constant(c) => c.max_element() > 0.0,
            Environment::LatLong { texels, .. } => texels.iter().any(|t| t.max_element() > 0.0),
        };
        emitter || light || environment
    }
}

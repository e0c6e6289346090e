//! Texture images: read once per glTF image and use, decoded, and converted from sRGB to
//! linear (base colour, emissive) or to tangent-space vectors (normal maps).

use glam::Vec3;

use super::{accessors, source, Loader};
use crate::scene::error::ResourceError;
use crate::scene::{SceneError, Texture};

/// How a texture's texels are stored in the [`Texture`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Encoding {
    /// Colour: sRGB-decoded to linear RGB.
    Srgb,
    /// Data stored linearly (a metallicRoughnessTexture).
    Linear,
    /// A normal map with its `scale`: linear texels decoded to tangent-space vectors
    /// ([`prt_formats::normal_map::decode_texel`]).
    Normal { scale: f32 },
}

impl Encoding {
    /// The key of a decoded image: one image read as colour and as a normal map (or at two
    /// scales) is two textures.
    fn key(self) -> u32 {
        match self {
            Encoding::Srgb => u32::MAX,
            Encoding::Linear => u32::MAX - 1,
            Encoding::Normal { scale } => scale.to_bits(),
        }
    }
}

impl Loader<'_> {
    /// Loads (once per glTF image and encoding) the image behind a texture reference.
    pub(super) fn texture(
        &mut self,
        texture: gltf::Texture,
        tex_coord: u32,
        encoding: Encoding,
        material: &str,
        slot: &str,
    ) -> Result<usize, SceneError> {
        if tex_coord != 0 {
            self.warnings.push(format!(
                "{}: material \"{material}\": {slot} uses TEXCOORD_{tex_coord}; only TEXCOORD_0 \
                 is read",
                self.path.display(),
            ));
        }
        let image = texture.source();
        let index = image.index();
        if let Some(&t) = self.texture_of_image.get(&(index, encoding.key())) {
            return Ok(t);
        }
        let (label, bytes) = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let label = format!("buffer view {}", view.index());
                let bytes = accessors::view_bytes(&view, &self.buffers)
                    .map_err(|e| SceneError::Image {
                        path: self.path.to_path_buf(),
                        index,
                        source_label: label.clone(),
                        source: Box::new(ResourceError::View(e)),
                    })?
                    .to_vec();
                (label, bytes)
            }
            gltf::image::Source::Uri { uri, .. } => {
                let label = source::uri_label(uri);
                let bytes = self.read_uri(uri).map_err(|source| SceneError::Image {
                    path: self.path.to_path_buf(),
                    index,
                    source_label: label.clone(),
                    source: Box::new(source),
                })?;
                (label, bytes)
            }
        };
        let img = image::load_from_memory(&bytes).map_err(|e| SceneError::Image {
            path: self.path.to_path_buf(),
            index,
            source_label: label.clone(),
            source: Box::new(ResourceError::Decode(e)),
        })?;
        let rgb = img.to_rgb32f();
        let (width, height) = (rgb.width(), rgb.height());
        let texels = rgb
            .pixels()
            .map(|p| match encoding {
                Encoding::Srgb => Vec3::new(
                    srgb_to_linear(p.0[0]),
                    srgb_to_linear(p.0[1]),
                    srgb_to_linear(p.0[2]),
                ),
                Encoding::Linear => Vec3::from_array(p.0),
                Encoding::Normal { scale } => {
                    Vec3::from_array(prt_formats::normal_map::decode_texel(p.0, scale))
                }
            })
            .collect();
        let name = image
            .name()
            .map(str::to_owned)
            .unwrap_or_else(|| label.trim_matches('"').to_owned());
        self.textures.push(Texture {
            name,
            width,
            height,
            texels,
        });
        let t = self.textures.len() - 1;
        self.texture_of_image.insert((index, encoding.key()), t);
        Ok(t)
    }
}

/// The sRGB transfer function, inverted (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_endpoints() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214).abs() < 1e-3);
    }
}

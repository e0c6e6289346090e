//! Texture images (base colour, emissive): read once per glTF image, decoded, and converted
//! from sRGB to linear.

use glam::Vec3;

use super::{accessors, source, Loader};
use crate::scene::error::ResourceError;
use crate::scene::{SceneError, Texture};

impl Loader<'_> {
    /// Loads (once per glTF image) the image behind a texture reference, sRGB-decoded.
    pub(super) fn texture(
        &mut self,
        info: &gltf::texture::Info,
        material: &str,
        slot: &str,
    ) -> Result<usize, SceneError> {
        if info.tex_coord() != 0 {
            self.warnings.push(format!(
                "{}: material \"{material}\": {slot} uses TEXCOORD_{}; only TEXCOORD_0 is read",
                self.path.display(),
                info.tex_coord()
            ));
        }
        let image = info.texture().source();
        let index = image.index();
        if let Some(&t) = self.texture_of_image.get(&index) {
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
            .map(|p| {
                Vec3::new(
                    srgb_to_linear(p.0[0]),
                    srgb_to_linear(p.0[1]),
                    srgb_to_linear(p.0[2]),
                )
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
        self.texture_of_image.insert(index, t);
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

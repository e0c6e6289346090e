//! The `[vertex]` table of the bake config (docs/config.md): the per-vertex bake's own
//! settings (`secondary`, `t0_terms`, `light_bins`), their defaults and their checks. Only the per-vertex
//! mode reads them, and they change with it; the rest of the config only holds the table, so
//! the table's keys and rules live here, beside one another.

use serde::Deserialize;

use super::validate::Checker;
use super::{ConfigError, Mode};

/// The `[vertex]` table: settings of the per-vertex bake (`mode = "vertex"`; docs/vertex.md).
/// Every key is optional. `spp` is N1 in vertex mode: the directions traced from each vertex
/// for T1 and T2.
#[derive(Clone, Debug, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VertexConfig {
    /// N2: directions sampled at each first hit, 1 ..= [`MAX_SECONDARY`] (default
    /// [`DEFAULT_SECONDARY`]).
    pub secondary: Option<u32>,
    /// Haar terms kept per T0 row, 1 ..= 6 x 64 x 64 (default
    /// [`prt_formats::vertex::DEFAULT_T0_TERMS`]).
    pub t0_terms: Option<u32>,
    /// T1 draws one direction in every light bin per first hit as well as the N2 BRDF
    /// directions, combined by multiple importance sampling (default true): far less
    /// speckle under small bright lights, for one shadow ray per bin above the horizon.
    pub light_bins: Option<bool>,
    /// Store T1 and T2 compressed (clustered Tucker; docs/vertex.md "Compression"; default
    /// true). The keys below tune it.
    pub compress: Option<bool>,
    /// Relative L2 error allowed per cluster of vertices and tensor, in [0, 1) (default
    /// `crate::vertex::DEFAULT_COMPRESS_ERROR`): the ranks are the smallest meeting it.
    pub compress_error: Option<f32>,
    /// Vertices per cluster aimed at; when absent (the default) each group starts at 128 and
    /// tries a neighbour of `crate::vertex::AUTO_CLUSTER_VERTICES`, keeping the smallest result
    /// meeting `compress_error` (128 when none does).
    pub cluster_vertices: Option<u32>,
    /// Largest light rank per cluster, 1 ..= 384 (default 64).
    pub light_rank: Option<u32>,
    /// Largest element (slot x SH) rank per cluster (default 64).
    pub element_rank: Option<u32>,
    /// Largest vertex rank per cluster (default 32).
    pub vertex_rank: Option<u32>,
}

pub use crate::vertex::{DEFAULT_SECONDARY, MAX_SECONDARY};

impl VertexConfig {
    /// N2, the default filled in.
    pub fn secondary(&self) -> u32 {
        self.secondary.unwrap_or(DEFAULT_SECONDARY)
    }

    /// Haar terms per T0 row, the default filled in.
    pub fn t0_terms(&self) -> u32 {
        self.t0_terms
            .unwrap_or(prt_formats::vertex::DEFAULT_T0_TERMS as u32)
    }

    /// Whether T1 samples every light bin, the default filled in.
    pub fn light_bins(&self) -> bool {
        self.light_bins.unwrap_or(true)
    }

    /// The compression settings, defaults filled in; None when `compress = false`.
    pub fn compression(&self) -> Option<prt_formats::clustered::CompressionSettings> {
        use crate::vertex::default_compression;
        if !self.compress.unwrap_or(true) {
            return None;
        }
        let d = default_compression();
        Some(prt_formats::clustered::CompressionSettings {
            error_target: self.compress_error.unwrap_or(d.error_target),
            cluster_vertices: self.cluster_vertices,
            max_light_rank: self.light_rank.unwrap_or(d.max_light_rank),
            max_element_rank: self.element_rank.unwrap_or(d.max_element_rank),
            max_vertex_rank: self.vertex_rank.unwrap_or(d.max_vertex_rank),
        })
    }

    /// Checks the table's values; `mode` is the config's, which must be `vertex` for the table
    /// to be there at all.
    pub(super) fn validate(&self, c: &Checker, mode: Mode) -> Result<(), ConfigError> {
        if mode != Mode::Vertex {
            return Err(c.err(
                "vertex",
                "the [vertex] table sets up a per-vertex bake; it needs `mode = \"vertex\"`",
            ));
        }
        if let Some(n) = self.secondary {
            c.range_u32("vertex.secondary", n, 1, MAX_SECONDARY)?;
        }
        if let Some(k) = self.t0_terms {
            let max = prt_formats::vertex::cube_len(prt_formats::vertex::DIRECT_CUBE) as u32;
            c.range_u32("vertex.t0_terms", k, 1, max)?;
        }
        if let Some(e) = self.compress_error {
            if !(e.is_finite() && (0.0..1.0).contains(&e)) {
                return Err(c.err(
                    "vertex.compress_error",
                    format!("{e} is not a relative error in [0, 1)"),
                ));
            }
        }
        let bins = prt_formats::vertex::cube_len(prt_formats::vertex::T1_LIGHT_CUBE) as u32;
        for (key, value, max) in [
            ("vertex.cluster_vertices", self.cluster_vertices, u32::MAX),
            ("vertex.light_rank", self.light_rank, bins),
            ("vertex.element_rank", self.element_rank, u32::MAX),
            ("vertex.vertex_rank", self.vertex_rank, u32::MAX),
        ] {
            if let Some(v) = value {
                c.range_u32(key, v, 1, max)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::BakeConfig;

    fn parse(text: &str) -> Result<BakeConfig, ConfigError> {
        BakeConfig::parse(text, "/scenes/x/bake.toml")
    }

    #[test]
    fn vertex_table_needs_vertex_mode_and_checks_its_keys() {
        let c = parse(
            "scene = \"x.gltf\"\nmode = \"vertex\"\n[vertex]\nsecondary = 8\nt0_terms = 24576",
        )
        .unwrap();
        let v = c.vertex.as_ref().unwrap();
        assert_eq!((v.secondary(), v.t0_terms()), (8, 24576));
        let d = VertexConfig::default();
        assert_eq!((d.secondary(), d.t0_terms(), d.light_bins()), (4, 96, true));
        assert_eq!(d.compression(), Some(crate::vertex::default_compression()));
        let off =
            parse("scene = \"x.gltf\"\nmode = \"vertex\"\n[vertex]\ncompress = false").unwrap();
        assert_eq!(off.vertex.unwrap().compression(), None);
        for (body, key) in [
            (
                "mode = \"vertex\"\n[vertex]\nsecondary = 0",
                "vertex.secondary",
            ),
            (
                "mode = \"vertex\"\n[vertex]\nsecondary = 65",
                "vertex.secondary",
            ),
            (
                "mode = \"vertex\"\n[vertex]\nt0_terms = 24577",
                "vertex.t0_terms",
            ),
            (
                "mode = \"vertex\"\n[vertex]\nt0_terms = 0",
                "vertex.t0_terms",
            ),
            ("mode = \"vertex\"\n[vertex]\nsecundary = 3", "secundary"),
            (
                "mode = \"vertex\"\n[vertex]\nlight_bins = \"yes\"",
                "light_bins",
            ),
            ("mode = \"vertex\"\n[vertex]\nlight_bins = 1", "light_bins"),
            (
                "mode = \"vertex\"\n[vertex]\ncompress_error = 1.0",
                "vertex.compress_error",
            ),
            (
                "mode = \"vertex\"\n[vertex]\ncompress_error = -0.1",
                "vertex.compress_error",
            ),
            (
                "mode = \"vertex\"\n[vertex]\ncompress_error = nan",
                "vertex.compress_error",
            ),
            (
                "mode = \"vertex\"\n[vertex]\ncluster_vertices = 0",
                "vertex.cluster_vertices",
            ),
            (
                "mode = \"vertex\"\n[vertex]\nlight_rank = 385",
                "vertex.light_rank",
            ),
            (
                "mode = \"vertex\"\n[vertex]\nelement_rank = 0",
                "vertex.element_rank",
            ),
            (
                "mode = \"vertex\"\n[vertex]\nvertex_rank = 0",
                "vertex.vertex_rank",
            ),
            ("mode = \"vertex\"\n[vertex]\ncompress = \"no\"", "compress"),
            ("[vertex]\nsecondary = 3", "mode = \"vertex\""),
        ] {
            let e = parse(&format!("scene = \"x.gltf\"\n{body}"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(key), "{body:?}: expected {key:?} in: {e}");
        }
    }
}

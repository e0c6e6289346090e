//! The bake config as written: serde reads the TOML into these structs with
//! `deny_unknown_fields` (a misspelt key is an error with its line and column); `validate.rs`
//! checks every value and builds the [`super::BakeConfig`].

use std::fmt;

use glam::Vec3;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

use super::{BasisConfig, MissingNormals, Mode, VertexConfig};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawConfig {
    pub(super) scene: String,
    pub(super) output: Option<String>,
    pub(super) mode: Option<Mode>,
    pub(super) width: Option<u32>,
    pub(super) height: Option<u32>,
    pub(super) spp: Option<u32>,
    pub(super) emission_oversampling: Option<u32>,
    pub(super) reflections: Option<u32>,
    pub(super) seed: Option<u64>,
    pub(super) missing_normals: Option<MissingNormals>,
    pub(super) environment: Option<RawEnvironment>,
    #[serde(default)]
    pub(super) materials: OrderedTables<RawMaterial>,
    pub(super) basis: Option<BasisConfig>,
    pub(super) camera: Option<RawCamera>,
    pub(super) vertex: Option<VertexConfig>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCamera {
    pub(super) position: [f32; 3],
    pub(super) target: [f32; 3],
    pub(super) fov: Option<f32>,
    /// Deprecated: the field of view in radians (accepted with a warning naming `fov`).
    pub(super) yfov: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawEnvironment {
    pub(super) color: Option<Rgb>,
    pub(super) map: Option<String>,
    pub(super) intensity: Option<f32>,
    pub(super) rotation: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMaterial {
    #[serde(default)]
    pub(super) editable: bool,
    pub(super) family: Option<String>,
    pub(super) kd: Option<Rgb>,
    pub(super) ks: Option<Rgb>,
    pub(super) shininess: Option<f32>,
    pub(super) alpha: Option<f32>,
}

/// A colour written either as `[r, g, b]` or as one number meaning gray.
pub(super) struct Rgb(pub(super) Vec3);

impl<'de> Deserialize<'de> for Rgb {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Rgb;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number (gray) or an array of 3 numbers [r, g, b]")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Rgb, E> {
                Ok(Rgb(Vec3::splat(v as f32)))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Rgb, E> {
                Ok(Rgb(Vec3::splat(v as f32)))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Rgb, E> {
                Ok(Rgb(Vec3::splat(v as f32)))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Rgb, A::Error> {
                let mut c = [0.0f32; 3];
                for (i, slot) in c.iter_mut().enumerate() {
                    *slot = seq
                        .next_element::<f32>()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(Rgb(Vec3::from_array(c)))
            }
        }
        d.deserialize_any(V)
    }
}

/// A TOML table of tables kept in file order (a `BTreeMap` would sort the names).
pub(super) struct OrderedTables<T>(pub(super) Vec<(String, T)>);

impl<T> Default for OrderedTables<T> {
    fn default() -> Self {
        OrderedTables(Vec::new())
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for OrderedTables<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = OrderedTables<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table of [materials.NAME] tables")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
                let mut out = Vec::new();
                while let Some((k, v)) = map.next_entry::<String, T>()? {
                    out.push((k, v));
                }
                Ok(OrderedTables(out))
            }
        }
        d.deserialize_map(V(std::marker::PhantomData))
    }
}

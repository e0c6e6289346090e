//! glTF 2.0 loading (to be completed).
use super::Scene;
use crate::config::BakeConfig;

pub fn load(_config: &BakeConfig) -> Result<Scene, String> {
    Err("scene loading is not implemented yet".into())
}

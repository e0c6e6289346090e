//! Bake file container and shared schemas.
pub mod basis;

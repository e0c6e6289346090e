//! Bake file container and shared schemas.

//! PRT baker: scene loading, ray queries, BRDF families and bases, bakers, reference path
//! tracer. See DESIGN.md and docs/ for the mathematics and conventions.

pub mod brdf;
pub mod scene;
pub mod config;

//! PRT baker: scene loading, ray queries, BRDF families and bases, bakers, reference path
//! tracer. See DESIGN.md and docs/ for the mathematics and conventions.

pub mod brdf;
pub mod scene;
pub mod config;
pub mod accel;
pub mod integrator;
pub mod lights;
pub mod sampling;
pub mod reference;
pub mod testing;
pub mod basis;
pub mod plot;

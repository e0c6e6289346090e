//! PRT baker: scene loading, ray queries, BRDF families and bases, bakers, reference path
//! tracer. docs/design.md says what each module holds; docs/ has the mathematics and
//! conventions.

pub mod accel;
pub mod basis;
pub mod brdf;
pub mod config;
pub mod error;
pub mod film_emission;
pub mod ground_truth;
pub mod integrator;
pub mod lights;
pub mod metrics;
pub mod pixel;
pub mod progress;
pub mod reference;
pub mod run;
pub mod sampling;
pub mod scene;
pub mod shard;
pub mod testing;
pub mod units;
pub mod vertex;
pub mod view;

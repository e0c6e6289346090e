//! What can go wrong laying out, baking or writing a per-pixel bake.

/// Why a per-pixel bake could not be made or written.
#[derive(Debug, thiserror::Error)]
pub enum PixelError {
    /// The caller cancelled the bake ([`crate::progress::Progress::cancelled`]).
    #[error(transparent)]
    Cancelled(#[from] crate::progress::Cancelled),
    /// An editable glossy material's family has no basis among those given.
    #[error(
        "material '{material}' is editable with family {family} but no basis for it was built"
    )]
    MissingBasis {
        /// The material's name.
        material: String,
        /// Its family.
        family: prt_formats::Family,
    },
    /// A basis was built with another size than the allocation planned for its family.
    #[error("the {family} basis has {built} BRDFs but the allocation planned {planned}")]
    BasisSize {
        /// The family.
        family: prt_formats::Family,
        /// Basis BRDFs the allocation planned.
        planned: usize,
        /// Basis BRDFs the basis has.
        built: usize,
    },
    /// A material would need more slots than a path vertex can carry.
    #[error("material '{material}' needs {slots} slots; at most {max} are supported (use fewer basis BRDFs)")]
    TooManySlots {
        /// The material's name.
        material: String,
        /// Slots it would need.
        slots: usize,
        /// [`crate::integrator::MAX_SLOTS`].
        max: usize,
    },
    /// The integrator given to [`bake_with`] was built for another image or path length.
    #[error("the integrator renders {integ_width}x{integ_height} with {integ_reflections} reflections but the bake asks for {width}x{height} with {reflections}")]
    IntegratorMismatch {
        /// The integrator's image width.
        integ_width: u32,
        /// The integrator's image height.
        integ_height: u32,
        /// The integrator's reflection count.
        integ_reflections: usize,
        /// The bake's image width.
        width: u32,
        /// The bake's image height.
        height: u32,
        /// The bake's reflection count.
        reflections: u32,
    },
    /// The bake file could not be written.
    #[error("writing {path}: {source}")]
    Write {
        /// The file.
        path: std::path::PathBuf,
        /// What went wrong (boxed: the container's error is large, and this is the cold path).
        source: Box<prt_formats::FormatError>,
    },
}

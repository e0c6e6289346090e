//! Values in and out: an f32 as the Python float it reads as ([`decimal`]); numpy arrays:
//! images are `float32` arrays of shape `(height, width, 3)`,
//! C-contiguous (row-major, top row first, linear RGB), the layout the runtime renders into,
//! so a render writes the array's own memory.

use numpy::{PyArray3, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::{message, Kind};

/// A new `(height, width, 3)` float32 array for a render to fill, its memory not yet written
/// (numpy's `empty`): zeroing it first would write the frame twice, and memory the allocator
/// hands back from an earlier frame is then reused without page faults (measured: zeros cost
/// a 512x512 frame about 3 ms more on a loaded two-core machine).
///
/// # Safety
/// The caller writes every element before the array reaches Python: the runtime's
/// `render_into` writes every float of a buffer of the right length and reads none, and on
/// its error the array is dropped unseen.
pub unsafe fn new_image(py: Python<'_>, width: u32, height: u32) -> Bound<'_, PyArray3<f32>> {
    // SAFETY: f32 has no invalid bit patterns, and see the function's contract.
    unsafe { PyArray3::<f32>::new(py, [height as usize, width as usize, 3], false) }
}

/// `out` as the array a `width` x `height` render writes into, or why it cannot be one.
pub fn output<'py>(
    out: &Bound<'py, PyAny>,
    width: u32,
    height: u32,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let wrong = |what: String| {
        message(
            Kind::Parameter,
            format!(
                "out: {what}; a {width}x{height} render needs a writable, C-contiguous float32 \
                 array of shape ({height}, {width}, 3)"
            ),
        )
    };
    let Ok(array) = out.cast::<PyUntypedArray>() else {
        return Err(wrong(format!(
            "a {}, not a numpy array",
            out.get_type().name()?
        )));
    };
    let shape = array.shape().to_vec();
    if shape != [height as usize, width as usize, 3] {
        return Err(wrong(format!("the array's shape is {shape:?}")));
    }
    let Ok(typed) = array.cast::<PyArray3<f32>>() else {
        return Err(wrong(format!("the array's dtype is {}", array.dtype())));
    };
    if !array.is_c_contiguous() {
        return Err(wrong("the array is not C-contiguous".into()));
    }
    if !out.getattr("flags")?.getattr("writeable")?.is_truthy()? {
        return Err(wrong("the array is read-only".into()));
    }
    Ok(typed.clone())
}

/// An RGB image given as an array-like of shape `(height, width, 3)` with a floating-point
/// dtype, as `(width, height, float32 values)`; `what` names it in errors. Integer, boolean or
/// complex arrays are refused rather than guessed at (an 8-bit image is not radiance).
pub fn rgb(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<(usize, usize, Vec<f32>)> {
    let np = py.import("numpy")?;
    let array = np.getattr("asarray")?.call1((image,))?;
    let array = array.cast::<PyUntypedArray>()?;
    let shape = array.shape().to_vec();
    let dtype = array.dtype();
    if shape.len() != 3 || shape[2] != 3 {
        return Err(message(
            Kind::Parameter,
            format!("{what}: an array of shape {shape:?}; give one of shape (height, width, 3)"),
        ));
    }
    if dtype.kind() != b'f' {
        return Err(message(
            Kind::Parameter,
            format!(
                "{what}: an array of dtype {dtype}; give linear RGB as floats (float32 or \
                 float64)"
            ),
        ));
    }
    let f32s = np
        .getattr("ascontiguousarray")?
        .call1((array, np.getattr("float32")?))?;
    let f32s = f32s.cast::<PyArray3<f32>>()?;
    let values = f32s.readonly().as_slice()?.to_vec();
    Ok((shape[1], shape[0], values))
}

/// Pixels as `[r, g, b]` triples (`values.len()` is a multiple of 3, as [`rgb`] gives).
pub fn pixels(values: &[f32]) -> Vec<[f32; 3]> {
    values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// An f32 as the Python float of its shortest decimal form (0.73, not 0.7300000190734863),
/// which converts back to the same f32: what a caller sees is what was set.
pub fn decimal(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(f64::from(v))
}

/// [`decimal`] of each of three.
pub fn decimals(v: [f32; 3]) -> (f64, f64, f64) {
    (decimal(v[0]), decimal(v[1]), decimal(v[2]))
}

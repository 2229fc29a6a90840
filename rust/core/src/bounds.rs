//! One-pass bounds checks of users' arrays (frequencies, speeds): NumPy needs a pass for the
//! minimum and another for the maximum, each over memory the previous core call has evicted.

/// Index of the first value of `a` outside the open interval (lo, hi), NaN included; None when
/// every value lies inside.
///
/// Blocks of 64 values are tested without branches (the comparisons vectorize); only a block
/// with a value outside is searched for its first one.
///
/// ```
/// use rotorid_core::bounds::first_outside;
/// assert_eq!(first_outside(&[1.0, 2.0, 3.0], 0.0, f64::INFINITY), None);
/// assert_eq!(first_outside(&[1.0, f64::NAN, -1.0], 0.0, f64::INFINITY), Some(1));
/// assert_eq!(first_outside(&[1.0, 2.0, f64::INFINITY], 0.0, f64::INFINITY), Some(2));
/// ```
pub fn first_outside(a: &[f64], lo: f64, hi: f64) -> Option<usize> {
    const BLOCK: usize = 64;
    let inside = |v: f64| v > lo && v < hi;
    for (b, block) in a.chunks(BLOCK).enumerate() {
        // `&` rather than `&&`: no early exit inside a block, so the loop vectorizes
        if !block.iter().fold(true, |all, &v| all & inside(v)) {
            return block.iter().position(|&v| !inside(v)).map(|i| b * BLOCK + i);
        }
    }
    None
}

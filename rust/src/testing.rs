//! What the unit tests of several modules share: RK4's order from an error's halving, a
//! frequency from zero crossings.

/// RK4's order: an error at `dt` over the same error at `dt / 2` (`coarse / fine`) within
/// `ratio` (16 for a fourth-order error, up to 32 for the per-step fifth order).
pub(crate) fn assert_halving_ratio(coarse: f64, fine: f64, ratio: std::ops::Range<f64>) {
    let r = coarse / fine;
    assert!(ratio.contains(&r), "{coarse:e} / {fine:e} = {r}");
}

/// The zero crossings of a signal worth `start` at t = 0 and `next()` after each of `steps`
/// steps of `dt` (each crossing's time linearly interpolated), and Hz, the frequency they give
/// (half a period between crossings, from the first to the last).
pub(crate) fn crossing_frequency(
    start: f64,
    steps: usize,
    dt: f64,
    mut next: impl FnMut() -> f64,
) -> (usize, f64) {
    let (mut crossings, mut first, mut last) = (0usize, f64::NAN, f64::NAN);
    let mut prev = start;
    for k in 1..=steps {
        let cur = next();
        if prev.signum() != cur.signum() {
            let tc = (k as f64 - cur / (cur - prev)) * dt;
            if first.is_nan() {
                first = tc;
            }
            last = tc;
            crossings += 1;
        }
        prev = cur;
    }
    let hz = 0.5 * crossings.saturating_sub(1) as f64 / (last - first);
    (crossings, hz)
}

//! One vehicle per lane: a kind's parameters for several vehicles (`f64` each) put side by side,
//! lane `l` of every value being vehicle `l`'s (`Controller::gather`, `Actuator::gather`). Each
//! value is copied from where it stands, never computed, so a lane holds exactly the bits of
//! its vehicle's value.

use super::Lane;

/// A value with one vehicle per lane, gathered from each vehicle's own (`From`): a lane value
/// from an `f64`, a row of them from a row, a struct of them (`Shared<L>`) from its `f64` form.
pub trait Gathered: Sized {
    /// The one-vehicle form (plain numbers: it borrows nothing).
    type From: 'static;
    /// Lane `l` of every number is `lane(l)`'s.
    fn gather_from<'a>(lane: impl Fn(usize) -> &'a Self::From + Copy) -> Self;
}

impl<L: Lane> Gathered for L {
    type From = f64;
    fn gather_from<'a>(lane: impl Fn(usize) -> &'a f64 + Copy) -> L {
        L::from_fn(|l| *lane(l))
    }
}

/// Element by element (rows of rows: a 4 x 4 matrix's every entry).
impl<T: Gathered, const N: usize> Gathered for [T; N] {
    type From = [T::From; N];
    fn gather_from<'a>(lane: impl Fn(usize) -> &'a [T::From; N] + Copy) -> Self {
        std::array::from_fn(|i| T::gather_from(move |l| &lane(l)[i]))
    }
}

/// The body of a `gather`: the struct `Ty { .. }` with one vehicle per lane, each listed field
/// gathered by its type (`Gathered`: a number, a row, a nested struct such as `Shared`) from
/// `at` (an expression of the lane index `l`: `each[l]`, the vehicle of lane `l`); the fields
/// after `;` are given as expressions (a flag over every lane, `each.iter().any(..)`).
///
/// ```ignore
/// fn gather<L: Lane>(each: &[&Pd]) -> Pd<L> {
///     gather!(|l| each[l] => Pd { shared, kp, kd; swing: each.iter().any(|p| p.swing) })
/// }
/// ```
macro_rules! gather {
    (
        |$l:ident| $at:expr => $Ty:ident {
            $($field:ident),* $(,)?
            $(; $($other:ident: $value:expr),+ $(,)?)?
        }
    ) => {
        $Ty {
            $($field: $crate::lane::Gathered::gather_from(|$l: usize| &$at.$field),)*
            $($($other: $value,)+)?
        }
    };
}
pub(crate) use gather;

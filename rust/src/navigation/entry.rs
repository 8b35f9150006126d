//! The navigation's work compiled once per lane type, in the instruction set of its lane
//! type (as the flight loop is, `integrate::entry`), and called from every vehicle's loop: the
//! filter does not depend on the vehicle, so it is not inlined into each of the loops.

use super::Navigation;
use crate::lane::{F64x4, KernelOps};
#[cfg(target_arch = "x86_64")]
use crate::lane::{F64x4Avx, F64x4Fma, F64x8Avx512, F64x8Fma512};
use crate::model::Rigid;

/// A lane type's navigation step (`Navigation::sense`), compiled for its instruction set.
pub trait Navigate: KernelOps {
    fn sense(nav: &mut Navigation<Self>, k: usize, truth: &Rigid<Self>);
}

macro_rules! portable {
    ($($ty:ty),+) => {$(
        impl Navigate for $ty {
            #[inline(never)]
            fn sense(nav: &mut Navigation<Self>, k: usize, truth: &Rigid<Self>) {
                nav.sense(k, truth)
            }
        }
    )+};
}
portable!(f64, F64x4);

macro_rules! intrinsic {
    ($($ty:ty => $features:literal, $sense:ident;)+) => {$(
        /// # Safety
        #[doc = concat!("The CPU must support ", $features, ".")]
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $sense(nav: &mut Navigation<$ty>, k: usize, truth: &Rigid<$ty>) {
            nav.sense(k, truth)
        }

        #[cfg(target_arch = "x86_64")]
        impl Navigate for $ty {
            fn sense(nav: &mut Navigation<Self>, k: usize, truth: &Rigid<Self>) {
                // SAFETY: a value of this lane type exists only on a CPU with its instruction
                // set (the flight loop's entry asserts it before making one).
                unsafe { $sense(nav, k, truth) }
            }
        }
    )+};
}
intrinsic! {
    F64x4Avx => "avx2", sense_avx2;
    F64x4Fma => "avx2,fma", sense_avx2_fma;
    F64x8Avx512 => "avx512f,avx512dq", sense_avx512;
    F64x8Fma512 => "avx512f,avx512dq", sense_avx512_fma;
}

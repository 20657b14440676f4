//! The float type of a simulation, chosen at run time, and the one place where it becomes a
//! type parameter ([`with_precision!`](crate::with_precision)).

use clap::ValueEnum;
use serde::{Deserialize, Serialize};

/// Float type of the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Single precision: the MCU's arithmetic (default).
    #[default]
    F32,
    /// Double precision (reference).
    F64,
}

impl Precision {
    /// `f32` or `f64`, as in figure titles.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

/// Evaluates `$body` with the type name `$T` bound to `f32` or `f64` as the [`Precision`]
/// `$p` says: `with_precision!(setup.precision, T => run::<T>(setup))`.
#[macro_export]
macro_rules! with_precision {
    ($p:expr, $T:ident => $body:expr) => {
        match $p {
            $crate::precision::Precision::F32 => {
                type $T = f32;
                $body
            }
            $crate::precision::Precision::F64 => {
                type $T = f64;
                $body
            }
        }
    };
}

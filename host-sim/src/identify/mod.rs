//! Parameter identification and comparison with measurements (thesis §3.3.2–3.3.4, §3.4.1):
//! the contact law from a drop test ([`contact`]), the suspension from a free decay
//! ([`free`]), synthetic drop tests made by the plant simulation ([`synth`]), and the fitted
//! parameters' uncertainty ([`uncertainty`]).

pub mod contact;
pub mod free;
pub mod synth;
pub mod uncertainty;

/// Solves the 3×3 system `a x = b` (nalgebra LU; `None` if singular or not finite).
pub(crate) fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let m = nalgebra::Matrix3::from_fn(|r, c| a[r][c]);
    let x = m.lu().solve(&nalgebra::Vector3::from(b))?;
    x.iter().all(|v| v.is_finite()).then(|| [x[0], x[1], x[2]])
}

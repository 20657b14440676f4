//! Switching events of several runs located at once (host grids): the Illinois searches of
//! the contact lanes' sub-steps that hold an event ([`super::stepper`]'s `switch_begin`), `K`
//! side by side in vector lanes, each with the operations of the stepper's search alone
//! (`SwitchSearch::locate`), so with the same points, decisions and result, bit for bit.
//!
//! A search whose dense output leaves the lanes' short sine (`|θ| > 0.5` rad, the wire
//! pendulum) reports no result; the caller locates that one alone.

use super::bracket::illinois_step;
use super::contact_lanes::LaneContact;
use super::dense::MAX_EVENT_EVALS;
use super::free::SmallTrig;
use super::isa::Isa;
use super::stepper::{EventCase, PendingSwitch, Simulator};
use crate::model::contact::LawCoeffs;
use crate::real::Real;

/// The event function's case as a lane code.
const LEAVES: u32 = 0;
const ARRIVES: u32 = 1;
const PRESSES: u32 = 2;

/// Up to `K` switching-event searches of runs with the suspension `F` and the linear law.
pub(crate) struct SwitchLanes<T: Real, F, const K: usize> {
    isa: Isa,
    /// Searches set (lanes `0..n`).
    n: usize,
    field: [F; K],
    /// The linear law's `k` (N/m) and `c` (N·s/m).
    k: [T; K],
    c: [T; K],
    /// The dense output: start `(x0, x1)`, its slope `(f0, f1)`, end `(y0, y1)`, its slope
    /// `(g0, g1)`, length `h` (s).
    x0: [T; K],
    x1: [T; K],
    f0: [T; K],
    f1: [T; K],
    y0: [T; K],
    y1: [T; K],
    g0: [T; K],
    g1: [T; K],
    h: [T; K],
    case: [u32; K],
    tol: [T; K],
    /// The event function at the ends.
    g_start: [T; K],
    g_end: [T; K],
}

impl<T: Real, F: LaneContact<T>, const K: usize> SwitchLanes<T, F, K> {
    /// No search set.
    pub(crate) fn new() -> Self {
        let z = [T::zero(); K];
        SwitchLanes {
            isa: Isa::detect(),
            n: 0,
            field: [F::default(); K],
            k: z,
            c: z,
            x0: z,
            x1: z,
            f0: z,
            f1: z,
            y0: z,
            y1: z,
            g0: z,
            g1: z,
            h: z,
            case: [0; K],
            tol: z,
            g_start: z,
            g_end: z,
        }
    }

    /// Searches set.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// Sets `sim`'s pending search into the next lane. Returns `false` (nothing set) if all
    /// are taken, or `sim` is not of this suspension and the linear law.
    #[inline]
    pub(crate) fn push(&mut self, sim: &Simulator<'_, T>, pending: &PendingSwitch<T>) -> bool {
        let i = self.n;
        let hammer = sim.hammer();
        let (true, Some(field), LawCoeffs::Linear { k, c }) =
            (i < K, F::of(&hammer.free_flight()), hammer.switch().law)
        else {
            return false;
        };
        let s = &pending.search;
        let d = &s.dense;
        self.field[i] = field;
        (self.k[i], self.c[i]) = (k, c);
        (self.x0[i], self.x1[i], self.f0[i], self.f1[i]) = (d.x0[0], d.x0[1], d.f0[0], d.f0[1]);
        (self.y0[i], self.y1[i], self.g0[i], self.g1[i]) = (d.x1[0], d.x1[1], d.f1[0], d.f1[1]);
        self.h[i] = d.h;
        self.case[i] = match s.case {
            EventCase::Leaves => LEAVES,
            EventCase::Arrives => ARRIVES,
            EventCase::Presses => PRESSES,
        };
        self.tol[i] = s.tol;
        (self.g_start[i], self.g_end[i]) = s.ends;
        self.n += 1;
        true
    }

    /// Locates the events of the searches set, as fractions of their sub-steps (`None`: a
    /// sine outside the short range, to be located alone), and clears the lanes.
    pub(crate) fn locate(&mut self) -> [Option<T>; K] {
        // Lanes not set take no step (their ends do not bracket a zero).
        for i in self.n..K {
            (self.g_start[i], self.g_end[i]) = (T::from_f64(1.0), T::from_f64(1.0));
            self.tol[i] = T::from_f64(1.0);
        }
        self.n = 0;
        match self.isa {
            // SAFETY: the CPU supports the variant's instructions (`Isa::detect`).
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            #[allow(unsafe_code)]
            Isa::Avx512 => unsafe { self.locate_avx512() },
            // SAFETY: as above.
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            #[allow(unsafe_code)]
            Isa::Avx2 => unsafe { self.locate_avx2() },
            Isa::Portable => self.locate_kernel(),
        }
    }

    /// [`SwitchLanes::locate`] compiled for AVX-512.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx,avx2,avx512f,avx512vl,avx512dq,avx512bw")]
    fn locate_avx512(&self) -> [Option<T>; K] {
        self.locate_kernel()
    }

    /// [`SwitchLanes::locate`] compiled for AVX2.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx,avx2")]
    fn locate_avx2(&self) -> [Option<T>; K] {
        self.locate_kernel()
    }

    /// The searches lane by lane, branch-free: each round one point of every search still
    /// going ([`illinois_step`]), its dense-output state (`DenseStep::at`), penetration
    /// (`Hammer::penetration`, the lanes' short sine) and event function (`EventCase::value`
    /// of the linear law).
    #[inline(always)]
    fn locate_kernel(&self) -> [Option<T>; K] {
        let zero = T::zero();
        let one = T::from_f64(1.0);
        let two = T::from_f64(2.0);
        let three = T::from_f64(3.0);
        let mut lo = [zero; K];
        let mut hi = [one; K];
        let mut g_lo = self.g_start;
        let mut g_hi = self.g_end;
        let mut side = [0u32; K];
        let mut searching = [0u32; K];
        let mut exact = [1u32; K];
        for i in 0..K {
            let brackets = (g_lo[i] <= zero) & (g_hi[i] > zero);
            searching[i] = u32::from(brackets);
            // Where the ends do not bracket a rising zero: the end `illinois` gives.
            let end = if g_lo[i] > zero { zero } else { one };
            lo[i] = if brackets { zero } else { end };
            hi[i] = if brackets { one } else { end };
        }
        for _ in 0..MAX_EVENT_EVALS {
            let mut mids = [zero; K];
            let mut going = 0u32;
            for i in 0..K {
                let on = (searching[i] != 0) & (hi[i] - lo[i] > self.tol[i]);
                searching[i] = u32::from(on);
                going |= searching[i];
                mids[i] = illinois_step(lo[i], hi[i], g_lo[i], g_hi[i]);
            }
            if going == 0 {
                break;
            }
            let mut g_mid = [zero; K];
            for i in 0..K {
                // `DenseStep::at`, component by component.
                let s = mids[i];
                let s2 = s * s;
                let s3 = s2 * s;
                let h00 = two * s3 - three * s2 + one;
                let h10 = (s3 - two * s2 + s) * self.h[i];
                let h01 = three * s2 - two * s3;
                let h11 = (s3 - s2) * self.h[i];
                let u0 = self.x0[i] * h00 + self.f0[i] * h10 + self.y0[i] * h01 + self.g0[i] * h11;
                let u1 = self.x1[i] * h00 + self.f1[i] * h10 + self.y1[i] * h01 + self.g1[i] * h11;
                let (d, dd, _, ok) = self.field[i].penetration::<SmallTrig>(u0, u1);
                let f = self.k[i] * d + self.c[i] * dd;
                let case = self.case[i];
                g_mid[i] = if case == LEAVES {
                    -f
                } else if case == ARRIVES {
                    d
                } else {
                    f
                };
                exact[i] &= u32::from(ok) | (searching[i] ^ 1);
            }
            for i in 0..K {
                let on = searching[i] != 0;
                let above = g_mid[i] > zero;
                let (up, down) = (on & above, on & !above);
                let halve_lo = up & (side[i] == 1);
                let halve_hi = down & (side[i] == 2);
                let half = T::from_f64(0.5);
                hi[i] = if up { mids[i] } else { hi[i] };
                lo[i] = if down { mids[i] } else { lo[i] };
                g_lo[i] = if down {
                    g_mid[i]
                } else if halve_lo {
                    g_lo[i] * half
                } else {
                    g_lo[i]
                };
                g_hi[i] = if up {
                    g_mid[i]
                } else if halve_hi {
                    g_hi[i] * half
                } else {
                    g_hi[i]
                };
                side[i] = if up {
                    1
                } else if down {
                    2
                } else {
                    side[i]
                };
            }
        }
        core::array::from_fn(|i| (exact[i] != 0).then_some(hi[i]))
    }
}

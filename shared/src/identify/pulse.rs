//! One impact's pulse inside its capture segment: the baseline before it (the sensor's offset
//! and noise at rest), the window of samples in contact, and the force's first and second
//! running integrals over that window, which give the penetration's rate and depth (the
//! hammer's momentum balance during contact, `m δ̈ = −F`).

use crate::capture::{PRE_TRIGGER, SEGMENT_LEN};

use super::DropRefusal;
use super::record::SegmentForce;

/// Samples at the start of a segment that make its baseline (the pre-trigger history less the
/// last 8 samples, where a smooth pulse may already rise).
pub const BASELINE_SAMPLES: usize = PRE_TRIGGER - 8;
/// Fewest samples a pulse must span to be fitted (a pulse shorter than this is not resolved by
/// the capture).
pub const MIN_PULSE_SAMPLES: usize = 8;
/// A sample belongs to the pulse when its force exceeds this many noise deviations.
pub const WINDOW_SIGMAS: f32 = 4.0;

/// Mean and variance of a segment's baseline, N and N².
pub fn baseline(seg: &SegmentForce) -> (f32, f32) {
    let b = &seg.force_n[..BASELINE_SAMPLES];
    let n = b.len() as f32;
    let mean = b.iter().sum::<f32>() / n;
    let var = b.iter().map(|f| (f - mean) * (f - mean)).sum::<f32>() / (n - 1.0);
    (mean, var)
}

/// A pulse's window and running integrals (time in samples).
#[derive(Debug, Clone, Copy)]
pub struct Pulse {
    /// First sample of the window in the segment.
    pub first: usize,
    /// Samples in the window.
    pub len: usize,
    /// Peak force, N.
    pub peak_n: f32,
    /// Force of the window's samples, offset removed, N (`len` used).
    pub force: [f32; SEGMENT_LEN],
    /// `∫F` from the window's first sample (trapezoid), N·samples.
    pub int1: [f32; SEGMENT_LEN],
    /// `∫∫F` from the window's first sample, N·samples².
    pub int2: [f32; SEGMENT_LEN],
    /// The force one sample before and after the window, N (at or below the window level).
    pub edges: (f32, f32),
}

impl Pulse {
    /// A pulse of no samples: the buffer [`Pulse::read`] fills (3 KiB: one is kept and reused,
    /// not returned by value, so that the stack holds one).
    pub const fn empty() -> Pulse {
        Pulse {
            first: 0,
            len: 0,
            peak_n: f32::MIN,
            force: [0.0; SEGMENT_LEN],
            int1: [0.0; SEGMENT_LEN],
            int2: [0.0; SEGMENT_LEN],
            edges: (0.0, 0.0),
        }
    }

    /// Reads into `self` the pulse of segment `k` (`seg`) with the baseline `offset_n` removed:
    /// the samples around the peak whose force exceeds `WINDOW_SIGMAS · sigma`. Only the first
    /// `len` samples of the arrays are the pulse's.
    ///
    /// # Errors
    /// [`DropRefusal::Clipped`] when the pulse reaches the baseline or the segment's end,
    /// [`DropRefusal::ShortPulse`] when it spans fewer than [`MIN_PULSE_SAMPLES`].
    #[inline(never)]
    pub fn read(
        &mut self,
        seg: &SegmentForce,
        k: usize,
        offset_n: f32,
        sigma_n: f32,
    ) -> Result<(), DropRefusal> {
        let p = self;
        p.peak_n = f32::MIN;
        let mut at = 0;
        for (j, f) in seg.force_n.iter().enumerate() {
            if f - offset_n > p.peak_n {
                p.peak_n = f - offset_n;
                at = j;
            }
        }
        let level = WINDOW_SIGMAS * sigma_n;
        let above = |j: usize| seg.force_n.get(j).is_some_and(|f| f - offset_n > level);
        let mut first = at;
        while first > 0 && above(first - 1) {
            first -= 1;
        }
        let mut last = at;
        while above(last + 1) {
            last += 1;
        }
        let impact = k as u16;
        if first < BASELINE_SAMPLES || last + 1 >= SEGMENT_LEN {
            return Err(DropRefusal::Clipped { impact });
        }
        p.first = first;
        p.len = last + 1 - first;
        if p.len < MIN_PULSE_SAMPLES {
            return Err(DropRefusal::ShortPulse {
                impact,
                samples: p.len as u16,
            });
        }
        let (mut i1, mut i2) = (0.0f32, 0.0f32);
        let mut prev = 0.0;
        for j in 0..p.len {
            let f = seg.force_n[first + j] - offset_n;
            if j > 0 {
                let step = 0.5 * (prev + f);
                i2 += i1 + 0.5 * step;
                i1 += step;
            }
            p.force[j] = f;
            p.int1[j] = i1;
            p.int2[j] = i2;
            prev = f;
        }
        p.edges = (
            seg.force_n[first - 1] - offset_n,
            seg.force_n[last + 1] - offset_n,
        );
        Ok(())
    }
}

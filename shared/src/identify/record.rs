//! What the on-board identification reads: a drop test recorded as segments around each impact
//! at the capture rate (the rig's [`Capture`], or the same segments on the desktop).

use crate::capture::{CAPTURE_RATE_HZ, Capture, SEGMENT_LEN};
use crate::control::SensorChain;
use crate::hal::ADC_MAX;

/// One recorded segment, in newtons.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentForce {
    /// Index of the segment's first sample since arming (time `start / CAPTURE_RATE_HZ` s).
    pub start: u32,
    /// Force of each sample on the sensor's calibration (offset not removed), N.
    pub force_n: [f32; SEGMENT_LEN],
    /// A sample sat on an ADC rail (code 0 or [`ADC_MAX`]): the force there is unknown.
    pub railed: bool,
}

/// A drop test's capture, read one segment at a time (no copy of the whole record is needed;
/// `&mut`: the firmware locks its capture for each read).
pub trait DropRecord {
    /// Segments (impacts) recorded.
    fn segments(&mut self) -> usize;
    /// Segment `k` (`k < segments()`), `None` when it is not recorded.
    fn segment(&mut self, k: usize) -> Option<SegmentForce>;
    /// Samples seen since arming, at [`CAPTURE_RATE_HZ`]: the record's length.
    fn samples(&mut self) -> u32;
    /// Samples lost since arming (a record with gaps has no trustworthy impact times).
    fn lost_samples(&mut self) -> u32;
    /// The trigger level, N: impacts weaker than this are not recorded.
    fn level_n(&mut self) -> f32;
    /// The force of one ADC code, N: the quantisation that bounds the noise from below.
    fn resolution_n(&mut self) -> f32;
}

/// The rig's capture read through its sensor calibration.
#[derive(Debug, Clone, Copy)]
pub struct CaptureOnChain<'a> {
    /// The capture (its segments are ADC codes).
    pub capture: &'a Capture,
    /// The calibration that turns codes into newtons.
    pub sensor: &'a SensorChain,
}

impl DropRecord for CaptureOnChain<'_> {
    fn segments(&mut self) -> usize {
        usize::from(self.capture.status().segments)
    }

    fn segment(&mut self, k: usize) -> Option<SegmentForce> {
        let view = self.capture.segment(u16::try_from(k).ok()?)?;
        let mut out = SegmentForce {
            start: view.start,
            force_n: [0.0; SEGMENT_LEN],
            railed: false,
        };
        for (f, &c) in out.force_n.iter_mut().zip(view.codes.iter()) {
            *f = self.sensor.force_n(c);
            out.railed |= c == 0 || c >= ADC_MAX;
        }
        Some(out)
    }

    fn samples(&mut self) -> u32 {
        self.capture.status().samples
    }

    fn lost_samples(&mut self) -> u32 {
        self.capture.lost_samples()
    }

    fn level_n(&mut self) -> f32 {
        self.capture.status().level_n
    }

    fn resolution_n(&mut self) -> f32 {
        self.sensor.force_n(1) - self.sensor.force_n(0)
    }
}

/// The capture's sample period, s.
pub const SAMPLE_PERIOD_S: f32 = 1.0 / CAPTURE_RATE_HZ as f32;

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

impl SegmentForce {
    /// The segment starting at sample `start` whose ADC codes are `codes`, read through
    /// `sensor`.
    pub fn of_codes(start: u32, codes: impl Iterator<Item = u16>, sensor: &SensorChain) -> Self {
        let mut out = SegmentForce {
            start,
            force_n: [0.0; SEGMENT_LEN],
            railed: false,
        };
        for (f, c) in out.force_n.iter_mut().zip(codes) {
            *f = sensor.force_n(c);
            out.railed |= c == 0 || c >= ADC_MAX;
        }
        out
    }
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
        Some(SegmentForce::of_codes(
            view.start,
            view.codes.into_iter(),
            self.sensor,
        ))
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
        self.sensor.code_step_n()
    }
}

/// The capture's sample period, s.
pub const SAMPLE_PERIOD_S: f32 = 1.0 / CAPTURE_RATE_HZ as f32;

/// A drop test's segments kept as bytes (a capture recorded once, replayed by the emulated
/// board's budget check and by the desktop): little-endian, the magic `DROP`, then `u32`
/// samples seen, `f32` trigger level (N), `u32` lost samples, `u32` segment count, and per
/// segment its `u32` start and [`SEGMENT_LEN`] `u16` codes. [`RecordedDrop::encode`] writes it.
#[derive(Debug, Clone, Copy)]
pub struct RecordedDrop<'a> {
    bytes: &'a [u8],
    segments: usize,
    samples: u32,
    level_n: f32,
    lost: u32,
    /// The calibration that turns codes into newtons.
    pub sensor: SensorChain,
}

/// Bytes of the header of a [`RecordedDrop`].
const HEADER: usize = 20;
/// Bytes of one segment of a [`RecordedDrop`].
const SEGMENT_BYTES: usize = 4 + 2 * SEGMENT_LEN;

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

impl<'a> RecordedDrop<'a> {
    /// Reads `bytes` (read through `sensor`), or `None` when they are not a whole record.
    pub fn parse(bytes: &'a [u8], sensor: SensorChain) -> Option<Self> {
        if bytes.get(..4)? != b"DROP" {
            return None;
        }
        let segments = usize::try_from(u32_at(bytes, 16)?).ok()?;
        if segments > crate::capture::SEGMENTS || bytes.len() != HEADER + segments * SEGMENT_BYTES {
            return None;
        }
        Some(RecordedDrop {
            bytes,
            segments,
            samples: u32_at(bytes, 4)?,
            level_n: f32::from_bits(u32_at(bytes, 8)?),
            lost: u32_at(bytes, 12)?,
            sensor,
        })
    }

    /// The bytes of `capture`'s segments, appended to `out`.
    pub fn encode(capture: &Capture, out: &mut impl Extend<u8>) {
        let st = capture.status();
        out.extend(*b"DROP");
        out.extend(st.samples.to_le_bytes());
        out.extend(st.level_n.to_bits().to_le_bytes());
        out.extend(capture.lost_samples().to_le_bytes());
        out.extend(u32::from(st.segments).to_le_bytes());
        for k in 0..st.segments {
            if let Some(seg) = capture.segment(k) {
                out.extend(seg.start.to_le_bytes());
                for c in seg.codes {
                    out.extend(c.to_le_bytes());
                }
            }
        }
    }
}

impl DropRecord for RecordedDrop<'_> {
    fn segments(&mut self) -> usize {
        self.segments
    }

    fn segment(&mut self, k: usize) -> Option<SegmentForce> {
        if k >= self.segments {
            return None;
        }
        let at = HEADER + k * SEGMENT_BYTES;
        let b = self.bytes.get(at..at + SEGMENT_BYTES)?;
        let codes = b
            .get(4..)?
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]));
        Some(SegmentForce::of_codes(u32_at(b, 0)?, codes, &self.sensor))
    }

    fn samples(&mut self) -> u32 {
        self.samples
    }

    fn lost_samples(&mut self) -> u32 {
        self.lost
    }

    fn level_n(&mut self) -> f32 {
        self.level_n
    }

    fn resolution_n(&mut self) -> f32 {
        self.sensor.code_step_n()
    }
}

//! The force capture for drop tests (thesis §3.3.2: the hammer released at rest near the
//! surface, several impacts), as segmented memory: while armed, the force signal is sampled at
//! [`CAPTURE_RATE_HZ`] (the firmware: ADC2 triggered by TIM3, DMA into a ring; the virtual rig:
//! the plant's force at every 10 µs step), and every rising crossing of the trigger level
//! records one segment of [`SEGMENT_LEN`] samples, [`PRE_TRIGGER`] of them before the crossing,
//! with the index of its first sample (its timestamp). A 0.57 ms contact is 57 samples; Fig.
//! 3.3's Hunt–Crossley contact, 1.2–1.5 ms at a drop's speeds, fits with its baseline.
//!
//! Memory: [`SEGMENTS`] × [`SEGMENT_LEN`] codes of 2 bytes = 16 KiB, static. The capture ends
//! when every segment is used, when its time is up, or on `capture stop`; the desktop then
//! reads the segments one per `capture get <k>` line ([`SegmentView`]'s text).

use crate::control::{SensorChain, within};

/// Capture sample rate, Hz.
pub const CAPTURE_RATE_HZ: u32 = 100_000;
/// Samples per segment (2.56 ms).
pub const SEGMENT_LEN: usize = 256;
/// Samples of a segment before the trigger crossing (0.32 ms).
pub const PRE_TRIGGER: usize = 32;
/// Segments (impacts) one capture holds.
pub const SEGMENTS: usize = 32;
/// Default trigger level, N (`capture arm` without a level).
pub const DEFAULT_LEVEL_N: f32 = 1.0;
/// Default capture time, s (`capture arm` without a time).
pub const DEFAULT_SECONDS: f32 = 2.0;
/// Longest capture time, s.
pub const CAPTURE_MAX_S: f32 = 60.0;

/// A `capture` console command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CaptureCommand {
    /// `capture`: the state line.
    Status,
    /// `capture arm [level_N] [seconds]`: start recording segments (drive idle).
    Arm {
        /// Trigger level, N.
        level_n: f32,
        /// Capture time from arming, s.
        seconds: f32,
    },
    /// `capture stop`: end the capture now (the segments stay readable).
    Stop,
    /// `capture get <k>`: segment `k` as one line.
    Get(u16),
    /// `capture identify`: the board's identification of the finished capture as a drop test
    /// ([`crate::identify`]).
    Identify,
    /// `capture adopt`: the same identification, and when the law fits, a draft of the active
    /// model with the identified contact and suspension (`draft apply` makes it active).
    Adopt,
}

/// Where a capture is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureState {
    /// Nothing recorded since power-up.
    Off,
    /// Recording: segments are taken at each trigger.
    Armed,
    /// Finished: the segments are readable.
    Done,
}

/// The capture's state (the `capture` reply).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureStatus {
    /// State.
    pub state: CaptureState,
    /// Segments recorded.
    pub segments: u16,
    /// Samples seen since arming.
    pub samples: u32,
    /// Trigger level, N.
    pub level_n: f32,
}

/// One recorded segment, copied out (the `capture get <k>` reply).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentView {
    /// Segment number.
    pub k: u16,
    /// Index of the first sample since arming (time `start / CAPTURE_RATE_HZ` s).
    pub start: u32,
    /// ADC codes.
    pub codes: [u16; SEGMENT_LEN],
}

/// The segmented capture. Feed every capture-rate sample to [`Capture::push`] (or blocks to
/// [`Capture::push_block`]).
#[derive(Debug, Clone)]
pub struct Capture {
    state: CaptureState,
    level_n: f32,
    level_code: u16,
    rearm_code: u16,
    /// The signal was below the re-arm level since the last segment ended.
    below: bool,
    history: [u16; PRE_TRIGGER],
    hist_head: usize,
    index: u32,
    end_index: u32,
    segs: [[u16; SEGMENT_LEN]; SEGMENTS],
    starts: [u32; SEGMENTS],
    count: usize,
    /// Samples written into the segment being recorded (0: waiting for a trigger).
    fill: usize,
    /// The first index that may trigger (a full pre-trigger history behind it).
    trigger_from: u32,
    /// Samples lost since arming ([`Capture::skip`]).
    lost: u32,
    /// Captures armed since power-up.
    arms: u32,
}

impl Default for Capture {
    fn default() -> Self {
        Self::new()
    }
}

impl Capture {
    /// An empty capture (`Off`). All zero, so that a static one costs no flash (`.bss`).
    pub const fn new() -> Self {
        Capture {
            state: CaptureState::Off,
            level_n: 0.0,
            level_code: 0,
            rearm_code: 0,
            below: false,
            history: [0; PRE_TRIGGER],
            hist_head: 0,
            index: 0,
            end_index: 0,
            segs: [[0; SEGMENT_LEN]; SEGMENTS],
            starts: [0; SEGMENTS],
            count: 0,
            fill: 0,
            trigger_from: 0,
            lost: 0,
            arms: 0,
        }
    }

    /// Arms a new capture (the previous segments are forgotten): trigger at `level_n` (N) on the
    /// sensor chain `sensor`, re-armed below half of it, for `seconds` (s). Arguments come from
    /// the console parser (level 0.1–100 N, 0.01–60 s); the trigger code is clamped to the
    /// ADC's range.
    pub fn arm(&mut self, sensor: &SensorChain, level_n: f32, seconds: f32) {
        let code = |f: f32| within(libm::ceilf(sensor.code_of(f)), 0.0, 4095.0) as u16;
        self.level_n = level_n;
        self.level_code = code(level_n);
        self.rearm_code = code(0.5 * level_n);
        self.below = false;
        self.hist_head = 0;
        self.index = 0;
        self.end_index = (seconds.max(0.0) * CAPTURE_RATE_HZ as f32) as u32;
        self.count = 0;
        self.fill = 0;
        self.trigger_from = PRE_TRIGGER as u32;
        self.lost = 0;
        self.arms = self.arms.wrapping_add(1);
        self.state = CaptureState::Armed;
    }

    /// Ends the capture (a segment being recorded is dropped).
    pub fn stop(&mut self) {
        if self.state == CaptureState::Armed {
            self.fill = 0;
            self.state = CaptureState::Done;
        }
    }

    /// Whether the capture is recording (the drive must stay idle).
    pub fn active(&self) -> bool {
        self.state == CaptureState::Armed
    }

    /// Captures armed since power-up (wrapping): a change tells the sampling input that a new
    /// capture starts.
    pub fn arm_count(&self) -> u32 {
        self.arms
    }

    /// Samples lost since arming (not delivered by the sampling input: [`Capture::skip`]).
    pub fn lost_samples(&self) -> u32 {
        self.lost
    }

    /// `n` samples were lost (a DMA block served too late, a re-armed stream): the index moves
    /// on by `n`, so later segments keep their time; a segment being recorded is dropped (it
    /// would have a hole), and the next trigger waits for a whole pre-trigger history of new
    /// samples and for the signal to fall below the re-arm level.
    pub fn skip(&mut self, n: u32) {
        if self.state != CaptureState::Armed || n == 0 {
            return;
        }
        self.lost = self.lost.saturating_add(n);
        if self.fill > 0 {
            self.fill = 0;
            self.below = false;
        }
        self.index = self.index.saturating_add(n);
        self.trigger_from = self.index.saturating_add(PRE_TRIGGER as u32);
        if self.index >= self.end_index {
            self.state = CaptureState::Done;
        }
    }

    /// The state line.
    pub fn status(&self) -> CaptureStatus {
        CaptureStatus {
            state: self.state,
            segments: self.count as u16,
            samples: self.index,
            level_n: self.level_n,
        }
    }

    /// Segment `k`, when recorded.
    pub fn segment(&self, k: u16) -> Option<SegmentView> {
        let i = usize::from(k);
        if i >= self.count {
            return None;
        }
        Some(SegmentView {
            k,
            start: *self.starts.get(i)?,
            codes: *self.segs.get(i)?,
        })
    }

    /// Feeds a block of consecutive samples (a DMA half-buffer).
    pub fn push_block(&mut self, codes: &[u16]) {
        if self.state != CaptureState::Armed {
            return;
        }
        for &c in codes {
            self.push(c);
        }
    }

    /// Feeds one sample (ADC code).
    pub fn push(&mut self, code: u16) {
        if self.state != CaptureState::Armed {
            return;
        }
        if self.fill > 0 {
            if let Some(slot) = self
                .segs
                .get_mut(self.count)
                .and_then(|s| s.get_mut(self.fill))
            {
                *slot = code;
            }
            self.fill += 1;
            if self.fill >= SEGMENT_LEN {
                self.fill = 0;
                self.count += 1;
                self.below = false;
                if self.count >= SEGMENTS {
                    self.state = CaptureState::Done;
                }
            }
        } else if self.below && code >= self.level_code && self.index >= self.trigger_from {
            if let (Some(seg), Some(start)) = (
                self.segs.get_mut(self.count),
                self.starts.get_mut(self.count),
            ) {
                for (i, slot) in seg.iter_mut().take(PRE_TRIGGER).enumerate() {
                    *slot = self
                        .history
                        .get((self.hist_head + i) % PRE_TRIGGER)
                        .copied()
                        .unwrap_or(0);
                }
                if let Some(slot) = seg.get_mut(PRE_TRIGGER) {
                    *slot = code;
                }
                *start = self.index - PRE_TRIGGER as u32;
                self.fill = PRE_TRIGGER + 1;
            }
        } else if code < self.rearm_code {
            self.below = true;
        }
        if let Some(h) = self.history.get_mut(self.hist_head) {
            *h = code;
        }
        self.hist_head = (self.hist_head + 1) % PRE_TRIGGER;
        self.index = self.index.wrapping_add(1);
        if self.fill == 0 && self.index >= self.end_index {
            self.state = CaptureState::Done;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// A half-sine force pulse of `peak` N and `len` samples starting at sample `at`, on the
    /// default sensor chain's codes.
    fn signal(n: usize, pulses: &[(usize, usize, f32)]) -> Vec<u16> {
        let s = SensorChain::default();
        (0..n)
            .map(|i| {
                let f: f32 = pulses
                    .iter()
                    .filter(|&&(at, len, _)| i >= at && i < at + len)
                    .map(|&(at, len, peak)| {
                        peak * libm::sinf(core::f32::consts::PI * (i - at) as f32 / len as f32)
                    })
                    .sum();
                libm::roundf(s.code_of(f)) as u16
            })
            .collect()
    }

    #[test]
    fn each_impact_gets_one_segment_with_its_onset_and_timestamp() {
        let sig = signal(
            20_000,
            &[(1_000, 57, 40.0), (5_000, 57, 13.0), (9_000, 57, 4.0)],
        );
        let mut c = Capture::new();
        c.arm(&SensorChain::default(), 1.0, 0.2);
        for block in sig.chunks(64) {
            c.push_block(block);
        }
        assert_eq!(c.status().state, CaptureState::Done); // 0.2 s = 20,000 samples
        assert_eq!(c.status().segments, 3);
        let s = SensorChain::default();
        let level = libm::ceilf(s.code_of(1.0)) as u16;
        for (k, at) in [(0u16, 1_000u32), (1, 5_000), (2, 9_000)] {
            let seg = c.segment(k).unwrap();
            // The crossing sample sits at PRE_TRIGGER, the segment starts PRE_TRIGGER before.
            let cross = seg.start as usize + PRE_TRIGGER;
            assert!(sig[cross] >= level && sig[cross - 1] < level, "{k}");
            assert!(
                cross >= at as usize && cross < at as usize + 10,
                "{k}: {cross}"
            );
            // The recorded codes are the signal's, including the pre-trigger history.
            assert_eq!(&seg.codes[..], &sig[seg.start as usize..][..SEGMENT_LEN]);
        }
        assert!(c.segment(3).is_none());
    }

    #[test]
    fn a_pulse_longer_than_a_segment_triggers_once_and_the_store_fills_up() {
        // One long contact (300 samples above the level): one segment, no retrigger until the
        // force has fallen below half the level.
        let sig = signal(2_000, &[(100, 300, 20.0)]);
        let mut c = Capture::new();
        c.arm(&SensorChain::default(), 1.0, 1.0);
        c.push_block(&sig);
        assert_eq!(c.status().segments, 1);
        // Many short pulses: the store holds SEGMENTS of them, then the capture is done.
        let pulses: Vec<(usize, usize, f32)> = (0..50).map(|i| (100 + 400 * i, 50, 10.0)).collect();
        let sig = signal(25_000, &pulses);
        c.arm(&SensorChain::default(), 1.0, 10.0);
        c.push_block(&sig);
        assert_eq!(c.status().segments as usize, SEGMENTS);
        assert_eq!(c.status().state, CaptureState::Done);
        // Stop keeps what was recorded.
        c.arm(&SensorChain::default(), 1.0, 10.0);
        c.push_block(&sig[..1_000]);
        c.stop();
        assert_eq!(c.status().segments, 2);
        assert!(!c.active());
    }

    #[test]
    fn lost_samples_keep_the_segments_time_and_never_splice_a_segment() {
        let sig = signal(4_000, &[(1_000, 57, 40.0), (3_000, 57, 40.0)]);
        let mut c = Capture::new();
        c.arm(&SensorChain::default(), 1.0, 1.0);
        let armed = c.arm_count();
        // Blocks up to the first pulse's middle, then two blocks lost (the DMA served late),
        // then the rest: the first pulse's segment would have a hole, so it is dropped; the
        // second keeps its time.
        c.push_block(&sig[..1_024]);
        c.skip(128);
        c.push_block(&sig[1_152..]);
        assert_eq!(c.lost_samples(), 128);
        assert_eq!(c.status().samples, 4_000);
        assert_eq!(c.status().segments, 1);
        let seg = c.segment(0).unwrap();
        assert!((2_968..2_978).contains(&seg.start), "{}", seg.start);
        assert_eq!(&seg.codes[..], &sig[seg.start as usize..][..SEGMENT_LEN]);

        // A loss right before a crossing: no trigger until a whole pre-trigger history of new
        // samples is in (the history holds samples from before the hole).
        c.arm(&SensorChain::default(), 1.0, 1.0);
        assert_ne!(c.arm_count(), armed);
        assert_eq!(c.lost_samples(), 0);
        c.push_block(&sig[..990]);
        c.skip(20);
        c.push_block(&sig[1_010..]);
        for k in 0..c.status().segments {
            let seg = c.segment(k).unwrap();
            assert!(
                seg.start >= 1_010,
                "segment {k} starts at {} in the hole",
                seg.start
            );
            assert_eq!(&seg.codes[..], &sig[seg.start as usize..][..SEGMENT_LEN]);
        }
        // A loss past the capture's end ends it.
        c.arm(&SensorChain::default(), 1.0, 0.01);
        c.skip(5_000);
        assert_eq!(c.status().state, CaptureState::Done);
    }
}

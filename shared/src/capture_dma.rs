//! The capture's DMA double buffer, as the capture task serves it: which block to hand to the
//! segment store ([`crate::capture::Capture`]), how many samples were lost, and when the stream
//! must be re-armed. The firmware implements [`CaptureStream`] over the STM32F407's DMA2
//! stream 2 and ADC2 (TIM3 triggers ADC2 at [`crate::capture::CAPTURE_RATE_HZ`]); the
//! bookkeeping here is tested on the desktop against a model of that hardware.
//!
//! The stream runs in double-buffer mode (RM0090 Rev 19 §10.3.9): it fills buffer M0, then M1,
//! then M0 again, [`BLOCK_LEN`] samples each, with no help from the CPU, and flags each full
//! buffer (TCIF). Its position — the buffer being filled (`DMA_SxCR.CT`) and the transfers left
//! in it (`DMA_SxNDTR`) — gives the samples written modulo two blocks; the µs clock since the
//! start gives them to a few samples. Together they give the exact count, so a service that
//! comes late sees how many blocks passed since the last one:
//! - the newest complete block is handed over, the ones before it (written over by now) are
//!   counted lost ([`Service::lost_samples`]);
//! - after the copy, the position is read again: if the stream has started writing over the
//!   block being copied, the copy is discarded and counted lost;
//! - a stream that stopped (`EN` = 0 after a transfer error, TEIF or DMEIF set, §10.3.18), an
//!   ADC that overran (OVR: it then sends no more DMA requests, §13.8.1), or a position that
//!   disagrees with the clock (the stream stalled) is re-armed ([`CaptureStream::rearm`]): the
//!   samples since the last block handed over are counted lost, and the count goes on from the
//!   clock (to ±2 samples: a re-armed stream starts at the next trigger).
//!
//! A new capture starts a new ring ([`BlockTracker::start`], after the stream was re-armed):
//! no sample of an earlier capture, left in a half-filled buffer, reaches it.

/// Samples per block (half of the double buffer): 0.64 ms at 100 kHz.
pub const BLOCK_LEN: usize = 64;
/// Samples in the ring of two blocks.
const RING_LEN: u32 = 2 * BLOCK_LEN as u32;
/// The capture's sample period, µs (100 kHz: [`crate::capture::CAPTURE_RATE_HZ`]).
pub const SAMPLE_PERIOD_US: u32 = 1_000_000 / crate::capture::CAPTURE_RATE_HZ;
const _: () = assert!(SAMPLE_PERIOD_US * crate::capture::CAPTURE_RATE_HZ == 1_000_000);
/// How far the stream's count may be from the clock's before the stream is taken as stalled,
/// samples (the clock's estimate is within 2 of the count when the stream runs).
pub const STALL_TOLERANCE: u32 = 8;

/// What the stream and its ADC show at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamState {
    /// The stream is enabled (`DMA_SxCR.EN`).
    pub enabled: bool,
    /// The buffer being filled: 0 (M0) or 1 (M1) (`DMA_SxCR.CT`).
    pub target: u8,
    /// Transfers left in it, `1 ..= BLOCK_LEN` (`DMA_SxNDTR`).
    pub remaining: u16,
    /// A transfer or direct-mode error is flagged (TEIF, DMEIF).
    pub error: bool,
    /// The ADC overran (`ADC_SR.OVR`).
    pub adc_overrun: bool,
    /// The µs clock (wrapping).
    pub now_us: u32,
}

/// The capture's DMA stream and ADC.
pub trait CaptureStream {
    /// Clears the stream's transfer-complete flag (TCIF).
    fn clear_complete(&mut self);
    /// The stream's state; `target` and `remaining` read as one consistent pair.
    fn state(&mut self) -> StreamState;
    /// Copies buffer `target` (0: M0, 1: M1).
    fn copy(&mut self, target: u8, out: &mut [u16; BLOCK_LEN]);
    /// Re-arms the stream (RM0090 §10.3.17, §13.8.1): disabled, its flags cleared, the ADC's
    /// overrun cleared and its DMA requests on again, [`BLOCK_LEN`] transfers into M0, enabled.
    fn rearm(&mut self);
}

/// What one service handed over.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Service {
    /// Samples lost before the block (or, without a block, up to now).
    pub lost_samples: u32,
    /// A block was copied into the caller's buffer: it follows the lost samples.
    pub block: bool,
    /// The stream was re-armed.
    pub rearmed: bool,
}

/// The bookkeeping of one capture's ring of blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BlockTracker {
    running: bool,
    /// The clock when the ring (re)started, µs.
    base_us: u32,
    /// The next block of this ring to hand over.
    next: u32,
    /// Samples lost since the capture started.
    lost_total: u32,
    /// Re-arms since the capture started.
    rearms: u32,
}

impl BlockTracker {
    /// Not running.
    pub const fn new() -> Self {
        BlockTracker {
            running: false,
            base_us: 0,
            next: 0,
            lost_total: 0,
            rearms: 0,
        }
    }

    /// A capture starts: the stream was just re-armed and its trigger started at `now_us`.
    pub fn start(&mut self, now_us: u32) {
        *self = BlockTracker {
            running: true,
            base_us: now_us,
            ..BlockTracker::new()
        };
    }

    /// The capture's trigger stopped: later services hand nothing over.
    pub fn stop(&mut self) {
        self.running = false;
    }

    /// Whether a capture runs.
    pub fn running(&self) -> bool {
        self.running
    }

    /// Samples lost since the capture started.
    pub fn lost_samples(&self) -> u32 {
        self.lost_total
    }

    /// Times the stream was re-armed since the capture started.
    pub fn rearms(&self) -> u32 {
        self.rearms
    }

    /// Serves the stream (its transfer-complete or error interrupt, or a periodic check): the
    /// newest complete block into `out` when there is one, the samples lost before it, and a
    /// re-arm when the stream stopped or stalled.
    ///
    /// Not running, it hands nothing over but still clears the stream's flags (a block that
    /// completed as the capture stopped, an error): its interrupt would otherwise come again
    /// at once, for ever.
    pub fn service(&mut self, hw: &mut impl CaptureStream, out: &mut [u16; BLOCK_LEN]) -> Service {
        hw.clear_complete();
        let s = hw.state();
        if !self.running {
            if s.error {
                hw.rearm();
            }
            return Service::default();
        }
        let est = self.estimate(s.now_us);
        let written = resolve(s, est);
        let stalled = written.abs_diff(est) > STALL_TOLERANCE;
        if !s.enabled || s.error || s.adc_overrun || stalled {
            return self.recover(hw, est);
        }
        let complete = written / BLOCK_LEN as u32;
        if complete <= self.next {
            return Service::default();
        }
        let newest = complete - 1;
        let mut lost = (newest - self.next) * BLOCK_LEN as u32;
        hw.copy((newest % 2) as u8, out);
        // The stream writes this buffer again from sample (newest + 2) × BLOCK_LEN on.
        let after = hw.state();
        let written_after = resolve(after, self.estimate(after.now_us));
        let intact = written_after <= (newest + 2) * BLOCK_LEN as u32;
        if !intact {
            lost += BLOCK_LEN as u32;
        }
        self.next = complete;
        self.lost_total = self.lost_total.saturating_add(lost);
        Service {
            lost_samples: lost,
            block: intact,
            rearmed: false,
        }
    }

    /// Samples of this ring the clock says were converted by `now_us`.
    fn estimate(&self, now_us: u32) -> u32 {
        now_us.wrapping_sub(self.base_us) / SAMPLE_PERIOD_US
    }

    /// Re-arms the stream; the samples of this ring not handed over are lost.
    fn recover(&mut self, hw: &mut impl CaptureStream, est: u32) -> Service {
        let lost = est.saturating_sub(self.next * BLOCK_LEN as u32);
        hw.rearm();
        let now = hw.state().now_us;
        // The re-armed ring starts where the clock is; the samples converted between the
        // state read and the re-arm are lost too.
        let lost = lost.saturating_add(self.estimate(now).saturating_sub(est));
        self.base_us = now;
        self.next = 0;
        self.lost_total = self.lost_total.saturating_add(lost);
        self.rearms = self.rearms.saturating_add(1);
        Service {
            lost_samples: lost,
            block: false,
            rearmed: true,
        }
    }
}

/// Samples the stream has written since its ring started: its position in the ring (exact)
/// with the whole rings taken from the clock's estimate `est` (within a block).
fn resolve(s: StreamState, est: u32) -> u32 {
    let in_buffer = (BLOCK_LEN as u32).saturating_sub(u32::from(s.remaining));
    let pos = u32::from(s.target & 1) * BLOCK_LEN as u32 + in_buffer.min(BLOCK_LEN as u32 - 1);
    // The multiple of the ring nearest to est − pos.
    let rings = (est.saturating_add(RING_LEN / 2)).saturating_sub(pos) / RING_LEN;
    rings * RING_LEN + pos
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(target: u8, remaining: u16, now_us: u32) -> StreamState {
        StreamState {
            enabled: true,
            target,
            remaining,
            error: false,
            adc_overrun: false,
            now_us,
        }
    }

    #[test]
    fn the_position_and_the_clock_give_the_exact_count() {
        // 300 samples written: 2 rings (256) + 44 in M0: remaining 20.
        for est in 290..=310 {
            assert_eq!(resolve(state(0, 20, 0), est), 300, "{est}");
        }
        // Just after a block boundary: 128 written, M0 full restarted (remaining 64 in M0).
        assert_eq!(resolve(state(0, 64, 0), 127), 128);
        assert_eq!(resolve(state(0, 64, 0), 130), 128);
        // At start nothing is written, even if the clock says one sample.
        assert_eq!(resolve(state(0, 64, 0), 1), 0);
        assert_eq!(resolve(state(1, 64, 0), 66), 64);
    }
}

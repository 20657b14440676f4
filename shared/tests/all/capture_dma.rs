//! The capture's DMA bookkeeping (`shared::capture_dma`) against a model of the rig's hardware:
//! TIM3 triggering ADC2 every 10 µs, DMA2 stream 2 in double-buffer mode (RM0090 Rev 19
//! §10.3.9: M0, M1, M0, …, 64 transfers each, TCIF at each full buffer, CT the buffer being
//! filled, NDTR the transfers left), a transfer error that disables the stream (§10.3.18), an
//! ADC that overruns when its result is not taken and then sends no DMA request (§13.8.1), a
//! stalled request line, and TIM5 counting µs — all on one 84 MHz timer clock, as on the rig.
//! The capture task is played by the test: it serves the stream late, is preempted during its
//! copy, and stops and restarts the capture at any point.
//!
//! Every sample carries its conversion number, so the test sees what the store received: whole
//! blocks of consecutive conversions, each at the index the bookkeeping gives it (exact while
//! the stream runs, within 2 samples per re-arm after one), no conversion twice, none from
//! before the capture started, and the lost count equal to what was not delivered.

use proptest::prelude::*;
use shared::capture_dma::{BLOCK_LEN, BlockTracker, CaptureStream, Service, StreamState};

/// Timer clock ticks per µs (84 MHz: TIM2/3/5 on APB1 ×2).
const TICKS_PER_US: u64 = 84;
/// TIM3's period at 100 kHz, ticks.
const TIM3_PERIOD: u64 = 840;
/// From trigger to result: (15 + 12) ADC cycles at 21 MHz = 108 timer ticks.
const CONVERSION_TICKS: u64 = 108;
const BLOCK: u64 = BLOCK_LEN as u64;

/// The hardware.
#[derive(Debug, Clone)]
struct Rig {
    /// Timer-clock ticks since power-up.
    t: u64,
    /// TIM3's next update, when running.
    next_update: Option<u64>,
    /// Conversions since power-up (each sample's value is its number).
    conversions: u64,
    // DMA stream.
    enabled: bool,
    ct: u8,
    ndtr: u16,
    tcif: bool,
    teif: bool,
    bufs: [[u64; BLOCK_LEN]; 2],
    /// The request line is stuck: conversions are not taken (ADC2 then overruns).
    stuck: bool,
    /// ADC2 converts nothing (no flag at all: the stream just stops moving).
    dead: bool,
    // ADC2.
    ovr: bool,
    unread: bool,
    /// Ticks a copy of a buffer takes (the capture task preempted during it).
    copy_ticks: u64,
    /// The conversion numbers of the last copy.
    copied: [u64; BLOCK_LEN],
}

impl Rig {
    fn new() -> Self {
        Rig {
            t: 1_000,
            next_update: None,
            conversions: 0,
            enabled: false,
            ct: 0,
            ndtr: BLOCK_LEN as u16,
            tcif: false,
            teif: false,
            bufs: [[u64::MAX; BLOCK_LEN]; 2],
            stuck: false,
            dead: false,
            ovr: false,
            unread: false,
            copy_ticks: 0,
            copied: [0; BLOCK_LEN],
        }
    }

    fn now_us(&self) -> u32 {
        (self.t / TICKS_PER_US) as u32
    }

    /// TIM3 starts counting from `cnt` (its first update after `TIM3_PERIOD − cnt` ticks).
    fn start_trigger(&mut self, cnt: u64) {
        self.next_update = Some(self.t + TIM3_PERIOD - cnt % TIM3_PERIOD);
    }

    fn stop_trigger(&mut self) {
        self.next_update = None;
    }

    /// Runs the hardware to tick `until`.
    fn run_to(&mut self, until: u64) {
        while let Some(u) = self.next_update {
            let done = u + CONVERSION_TICKS;
            if done > until {
                break;
            }
            self.t = done;
            self.convert();
            self.next_update = Some(u + TIM3_PERIOD);
        }
        self.t = self.t.max(until);
    }

    fn run_for(&mut self, ticks: u64) {
        self.run_to(self.t + ticks);
    }

    /// Runs until the next full buffer (or `limit` ticks).
    fn run_to_complete(&mut self, limit: u64) {
        let end = self.t + limit;
        while !self.tcif && self.t < end && self.next_update.is_some() {
            let u = self.next_update.unwrap() + CONVERSION_TICKS;
            self.run_to(u.min(end));
        }
    }

    fn convert(&mut self) {
        if self.dead {
            return;
        }
        let n = self.conversions;
        self.conversions += 1;
        if self.ovr {
            return; // no DMA request after an overrun (§13.8.1)
        }
        if self.enabled && !self.stuck {
            let i = BLOCK_LEN - usize::from(self.ndtr);
            self.bufs[usize::from(self.ct)][i] = n;
            self.ndtr -= 1;
            if self.ndtr == 0 {
                self.ndtr = BLOCK_LEN as u16;
                self.ct ^= 1;
                self.tcif = true;
            }
            self.unread = false;
        } else if self.unread {
            self.ovr = true;
        } else {
            self.unread = true;
        }
    }

    /// A transfer error: TEIF set, the stream disabled by the hardware.
    fn transfer_error(&mut self) {
        self.teif = true;
        self.enabled = false;
    }
}

impl CaptureStream for Rig {
    fn clear_complete(&mut self) {
        self.tcif = false;
    }
    fn state(&mut self) -> StreamState {
        StreamState {
            enabled: self.enabled,
            target: self.ct,
            remaining: self.ndtr,
            error: self.teif,
            adc_overrun: self.ovr,
            now_us: self.now_us(),
        }
    }
    fn copy(&mut self, target: u8, out: &mut [u16; BLOCK_LEN]) {
        // Preempted: the DMA goes on meanwhile, and the copy sees the buffer as it is then.
        self.run_for(self.copy_ticks);
        self.copied = self.bufs[usize::from(target)];
        for (o, n) in out.iter_mut().zip(self.copied) {
            *o = n as u16;
        }
    }
    fn rearm(&mut self) {
        self.enabled = false;
        self.tcif = false;
        self.teif = false;
        self.ovr = false;
        self.unread = false;
        self.stuck = false;
        self.ndtr = BLOCK_LEN as u16;
        self.ct = 0;
        self.enabled = true;
        self.run_for(20);
    }
}

/// Runs to the next full buffer, which must come within three blocks' time.
fn complete(rig: &mut Rig) {
    rig.run_to_complete(3 * BLOCK * TIM3_PERIOD);
    assert!(rig.tcif, "no full buffer within three blocks: {rig:?}");
}

/// The capture task and the segment store's index, checking every block.
struct Task {
    tracker: BlockTracker,
    /// The conversions before this capture's first.
    first: u64,
    /// The capture's index: samples delivered or counted lost.
    index: u64,
    delivered: u64,
    lost: u64,
    last_delivered: Option<u64>,
    rearms: u32,
}

impl Task {
    /// Starts a capture the way the board does: the stream re-armed, then the trigger.
    fn start(rig: &mut Rig, phase: u64) -> Task {
        rig.rearm();
        let first = rig.conversions;
        rig.start_trigger(phase);
        let mut tracker = BlockTracker::new();
        tracker.start(rig.now_us());
        Task {
            tracker,
            first,
            index: 0,
            delivered: 0,
            lost: 0,
            last_delivered: None,
            rearms: 0,
        }
    }

    fn stop(&mut self, rig: &mut Rig) {
        rig.stop_trigger();
        self.tracker.stop();
    }

    /// One service, checked.
    fn serve(&mut self, rig: &mut Rig) -> Service {
        let mut out = [0u16; BLOCK_LEN];
        let s = self.tracker.service(rig, &mut out);
        self.index += u64::from(s.lost_samples);
        self.lost += u64::from(s.lost_samples);
        if s.rearmed {
            self.rearms += 1;
        }
        if s.block {
            let tags = rig.copied;
            for (j, w) in tags.windows(2).enumerate() {
                assert_eq!(w[1], w[0] + 1, "block torn at {j}: {tags:?}");
            }
            for (o, n) in out.iter().zip(tags) {
                assert_eq!(*o, n as u16);
            }
            assert!(
                tags[0] >= self.first,
                "a sample from before the capture: {tags:?}"
            );
            if let Some(last) = self.last_delivered {
                assert!(tags[0] > last, "conversion {} delivered twice", tags[0]);
            }
            // The block's index against its conversion numbers: exact until a re-arm.
            let at = (tags[0] - self.first) as i64;
            let slack = 2 * i64::from(self.rearms);
            assert!(
                (at - self.index as i64).abs() <= slack,
                "block of conversion {} at index {} (first {}, {} re-arms)",
                tags[0],
                self.index,
                self.first,
                self.rearms
            );
            self.last_delivered = Some(tags[BLOCK_LEN - 1]);
            self.index += BLOCK;
            self.delivered += BLOCK;
        }
        assert_eq!(u64::from(self.tracker.lost_samples()), self.lost);
        s
    }

    /// Conversions of this capture not accounted for (neither delivered nor counted lost).
    fn unaccounted(&self, rig: &Rig) -> i64 {
        (rig.conversions - self.first) as i64 - self.index as i64
    }
}

#[test]
fn a_timely_service_hands_over_every_block_in_order() {
    let mut rig = Rig::new();
    let mut task = Task::start(&mut rig, 0);
    for _ in 0..200 {
        rig.run_to_complete(10 * TIM3_PERIOD * BLOCK);
        assert!(rig.tcif);
        rig.run_for(5 * TICKS_PER_US);
        let s = task.serve(&mut rig);
        assert!(s.block && s.lost_samples == 0 && !s.rearmed, "{s:?}");
    }
    assert_eq!(task.delivered, 200 * BLOCK);
    assert_eq!(task.lost, 0);
    assert!(task.unaccounted(&rig) < 4, "{}", task.unaccounted(&rig));
}

#[test]
fn a_late_service_counts_the_blocks_written_over_and_hands_over_the_newest() {
    for late_blocks in 1..=5u64 {
        let mut rig = Rig::new();
        let mut task = Task::start(&mut rig, 300);
        complete(&mut rig);
        task.serve(&mut rig);
        // The next service comes `late_blocks` blocks and a half late.
        complete(&mut rig);
        rig.run_for(late_blocks * BLOCK * TIM3_PERIOD + BLOCK / 2 * TIM3_PERIOD);
        let s = task.serve(&mut rig);
        assert!(s.block && !s.rearmed, "{s:?}");
        assert_eq!(u64::from(s.lost_samples), late_blocks * BLOCK);
        // And on as before: no re-arm was needed, the index stays exact.
        for _ in 0..4 {
            complete(&mut rig);
            let s = task.serve(&mut rig);
            assert!(s.block && s.lost_samples == 0, "{s:?}");
        }
        assert_eq!(task.rearms, 0);
    }
}

#[test]
fn a_copy_overtaken_by_the_stream_is_discarded_and_counted() {
    let mut rig = Rig::new();
    let mut task = Task::start(&mut rig, 0);
    complete(&mut rig);
    task.serve(&mut rig);
    complete(&mut rig);
    // Served 60 samples after the buffer completed, preempted for 10 samples in the copy: the
    // stream starts writing the other buffer... and 74 samples in, the one being copied.
    rig.run_for(60 * TIM3_PERIOD);
    rig.copy_ticks = 75 * TIM3_PERIOD;
    let s = task.serve(&mut rig);
    assert!(!s.block && s.lost_samples == BLOCK_LEN as u32, "{s:?}");
    rig.copy_ticks = 0;
    for _ in 0..3 {
        complete(&mut rig);
        assert!(task.serve(&mut rig).block);
    }
}

#[test]
fn a_transfer_error_re_arms_the_stream_and_the_capture_goes_on() {
    let mut rig = Rig::new();
    let mut task = Task::start(&mut rig, 500);
    for _ in 0..3 {
        complete(&mut rig);
        task.serve(&mut rig);
    }
    // The stream stops in the middle of a block (TEIF, EN = 0); ADC2 then overruns and takes
    // no trigger for the DMA. The error interrupt serves it 200 µs later.
    rig.run_for(20 * TIM3_PERIOD);
    rig.transfer_error();
    rig.run_for(20 * TIM3_PERIOD);
    assert!(rig.ovr);
    let s = task.serve(&mut rig);
    assert!(s.rearmed && !s.block, "{s:?}");
    assert!(!rig.ovr && !rig.teif && rig.enabled);
    // 3 blocks delivered, then 40 samples converted and lost, within the re-arm's slack.
    assert!((38..=43).contains(&s.lost_samples), "{s:?}");
    for _ in 0..10 {
        complete(&mut rig);
        let s = task.serve(&mut rig);
        assert!(s.block && s.lost_samples == 0, "{s:?}");
    }
    assert!(
        task.unaccounted(&rig).abs() <= 4,
        "{}",
        task.unaccounted(&rig)
    );
}

#[test]
fn a_stream_stalled_is_re_armed_by_the_periodic_check() {
    let mut rig = Rig::new();
    let mut task = Task::start(&mut rig, 0);
    complete(&mut rig);
    task.serve(&mut rig);
    // The request line stops: no TCIF will come, ADC2 overruns. The report task's check,
    // 1 s later, re-arms the stream.
    rig.stuck = true;
    rig.run_for(100_000 * TIM3_PERIOD);
    let s = task.serve(&mut rig);
    assert!(s.rearmed, "{s:?}");
    assert!(s.lost_samples >= 99_900, "{s:?}");
    complete(&mut rig);
    assert!(task.serve(&mut rig).block);
    assert!(task.unaccounted(&rig).abs() <= 4);

    // ADC2 converts nothing and raises no flag: the stream's position stays while the clock
    // runs. Each check counts the second as lost, so the capture's index keeps time and the
    // capture still ends at its time.
    rig.dead = true;
    for second in 1..=3u32 {
        rig.run_for(100_000 * TIM3_PERIOD);
        let s = task.serve(&mut rig);
        assert!(s.rearmed && !s.block, "{second}: {s:?}");
        assert!(
            (99_900..=100_100).contains(&s.lost_samples),
            "{second}: {s:?}"
        );
    }
}

#[test]
fn a_new_capture_gets_no_sample_of_the_one_before() {
    for stop_after in [1u64, 20, 63, 64, 65, 100] {
        let mut rig = Rig::new();
        let mut task = Task::start(&mut rig, 0);
        complete(&mut rig);
        task.serve(&mut rig);
        // Stopped with the next buffer part-filled.
        rig.run_for(stop_after * TIM3_PERIOD);
        task.stop(&mut rig);
        rig.run_for(1_000 * TIM3_PERIOD);
        // A block that completed as the capture stopped, or an error, raises the stream's
        // interrupt: served while stopped, it hands nothing over but clears the flags (a flag
        // left set would raise the interrupt again at once, for ever).
        rig.tcif = true;
        if stop_after == 20 {
            rig.transfer_error();
        }
        assert!(!task.serve(&mut rig).block);
        assert!(
            !rig.tcif && !rig.teif,
            "a flag left set after a stopped service"
        );
        // The next capture: its first block holds only its own samples (`Task::serve` checks).
        let mut task = Task::start(&mut rig, 123);
        complete(&mut rig);
        let s = task.serve(&mut rig);
        assert!(s.block && s.lost_samples == 0, "{s:?}");
        assert_eq!(rig.copied[0], task.first);
    }
}

#[test]
fn the_model_sees_stale_samples_when_the_stream_is_not_re_armed() {
    // What the check above guards against: a restart that only starts the trigger again
    // continues the half-filled buffer, and the first block opens with the old capture's tail.
    let mut rig = Rig::new();
    let mut task = Task::start(&mut rig, 0);
    rig.run_for(30 * TIM3_PERIOD);
    task.stop(&mut rig);
    let old = rig.conversions;
    rig.start_trigger(0);
    complete(&mut rig);
    assert!(rig.tcif);
    assert!(
        rig.bufs[0][0] < old,
        "no stale sample: {:?}",
        &rig.bufs[0][..4]
    );
}

/// One step of a random schedule.
#[derive(Debug, Clone)]
enum Step {
    /// Run to the next full buffer, then serve after `delay_us` (0 – 3 blocks late), with the
    /// copy taking `copy_us`.
    Serve { delay_us: u64, copy_us: u64 },
    /// A transfer error after `after_us`.
    Error { after_us: u64 },
    /// The request line stalls for `for_us`, then a periodic check.
    Stall { for_us: u64 },
    /// Stop after `after_us`, restart after `gap_us` with TIM3 counting from `phase`.
    Restart {
        after_us: u64,
        gap_us: u64,
        phase: u64,
    },
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        8 => (0u64..2_000, 0u64..40).prop_map(|(delay_us, copy_us)| Step::Serve { delay_us, copy_us }),
        1 => (0u64..640).prop_map(|after_us| Step::Error { after_us }),
        1 => (700u64..5_000).prop_map(|for_us| Step::Stall { for_us }),
        1 => (0u64..700, 0u64..2_000, 0u64..840)
            .prop_map(|(after_us, gap_us, phase)| Step::Restart { after_us, gap_us, phase }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Whatever the service delays, errors, stalls and restarts: whole blocks in order at
    /// their index, no sample twice or from an earlier capture, and every conversion either
    /// delivered or counted lost.
    #[test]
    fn any_schedule_keeps_the_blocks_whole_in_order_and_accounted(
        steps in prop::collection::vec(step(), 1..60),
        phase in 0u64..840,
    ) {
        let mut rig = Rig::new();
        let mut task = Task::start(&mut rig, phase);
        for st in steps {
            match st {
                Step::Serve { delay_us, copy_us } => {
                    rig.run_to_complete(4 * BLOCK * TIM3_PERIOD);
                    rig.run_for(delay_us * TICKS_PER_US);
                    rig.copy_ticks = copy_us * TICKS_PER_US;
                    task.serve(&mut rig);
                    rig.copy_ticks = 0;
                }
                Step::Error { after_us } => {
                    rig.run_for(after_us * TICKS_PER_US);
                    rig.transfer_error();
                    rig.run_for(30 * TICKS_PER_US);
                    prop_assert!(task.serve(&mut rig).rearmed);
                }
                Step::Stall { for_us } => {
                    rig.stuck = true;
                    rig.run_for(for_us * TICKS_PER_US);
                    task.serve(&mut rig);
                    rig.stuck = false;
                }
                Step::Restart { after_us, gap_us, phase } => {
                    rig.run_for(after_us * TICKS_PER_US);
                    task.stop(&mut rig);
                    rig.run_for(gap_us * TICKS_PER_US);
                    task = Task::start(&mut rig, phase);
                }
            }
            // Everything converted since the capture started is delivered, counted lost, or
            // still in the ring (at most two blocks and the re-arms' slack).
            let open = task.unaccounted(&rig);
            prop_assert!(
                open >= -2 * i64::from(task.rearms) && open <= 2 * BLOCK as i64 + 2 * i64::from(task.rearms) + 2,
                "unaccounted {} after {} re-arms", open, task.rearms
            );
        }
    }
}

//! The shaker drive `A sin(Ω t)` from a 32-bit phase accumulator (direct digital synthesis): the
//! phase advances by an integer increment per sample, so no time is accumulated in f32 and
//! frequency changes are phase-continuous by construction. Frequency changes are slew-limited
//! and amplitude changes ramp (soft start, soft stop); both targets are clamped to the
//! [`Limits`] window.

use super::config::{DAC_MID, DriveChain, Limits, SAMPLE_RATE_HZ};
use super::within;

/// One full turn of the phase accumulator.
const TURN: f32 = 4_294_967_296.0;

/// `sin(2π · phase / 2³²)` to ~1e-7: quarter-wave symmetry and an odd Taylor polynomial to
/// `x¹³` on `[0, π/2]`.
pub fn sin_turn(phase: u32) -> f32 {
    let quadrant = phase >> 30;
    let mut r = phase & 0x3FFF_FFFF;
    if quadrant & 1 == 1 {
        r = 0x4000_0000 - r;
    }
    let x = r as f32 * (core::f32::consts::FRAC_PI_2 / 1_073_741_824.0);
    let x2 = x * x;
    let s = x
        * (1.0
            + x2 * (-1.0 / 6.0
                + x2 * (1.0 / 120.0
                    + x2 * (-1.0 / 5040.0
                        + x2 * (1.0 / 362_880.0
                            + x2 * (-1.0 / 39_916_800.0 + x2 * (1.0 / 6_227_020_800.0)))))));
    if quadrant >= 2 { -s } else { s }
}

/// One output sample of the generator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveSample {
    /// Commanded cart displacement, mm.
    pub displacement_mm: f32,
    /// DAC code, `0 ..= 4095`.
    pub code: u16,
    /// A new excitation cycle began at this sample (the phase wrapped through 0).
    pub cycle_start: bool,
}

/// The phase-accumulator sine generator.
#[derive(Debug, Clone)]
pub struct SineGenerator {
    phase: u32,
    increment: u32,
    target_increment: u32,
    max_increment_step: u32,
    amplitude_mm: f32,
    target_amplitude_mm: f32,
    ramp_mm_per_sample: f32,
    abort_mm_per_sample: f32,
    aborting: bool,
    limits: Limits,
    codes_per_mm: f32,
}

impl SineGenerator {
    /// A silent generator at `limits.freq_min_hz`. `limits` and `drive` must have passed
    /// [`super::ControllerConfig::validate`].
    pub fn new(limits: &Limits, drive: &DriveChain) -> Self {
        let fs = SAMPLE_RATE_HZ as f32;
        let step = limits.freq_slew_hz_per_s / fs / fs * TURN;
        let inc = increment_of(limits.freq_min_hz);
        SineGenerator {
            phase: 0,
            increment: inc,
            target_increment: inc,
            max_increment_step: (libm::roundf(step) as u32).max(1),
            amplitude_mm: 0.0,
            target_amplitude_mm: 0.0,
            ramp_mm_per_sample: limits.amp_ramp_mm_per_s / fs,
            abort_mm_per_sample: limits.abort_ramp_mm_per_s / fs,
            aborting: false,
            limits: *limits,
            codes_per_mm: drive.codes_per_mm(),
        }
    }

    /// Sets the target frequency (Hz), clamped to the window; reached at the slew limit.
    /// NaN leaves the target unchanged.
    pub fn set_freq_hz(&mut self, freq_hz: f32) {
        if freq_hz.is_nan() {
            return;
        }
        let f = within(freq_hz, self.limits.freq_min_hz, self.limits.freq_max_hz);
        self.target_increment = increment_of(f);
    }

    /// Jumps to `freq_hz` (clamped) without slewing: only while the drive is silent.
    /// Returns whether it jumped.
    pub fn jump_freq_hz(&mut self, freq_hz: f32) -> bool {
        if self.amplitude_mm > 0.0 {
            return false;
        }
        self.set_freq_hz(freq_hz);
        self.increment = self.target_increment;
        true
    }

    /// Sets the target amplitude (mm), clamped to `0 ..= amplitude_max_mm`, reached at the
    /// soft ramp rate. NaN means 0.
    pub fn set_amplitude_mm(&mut self, amplitude_mm: f32) {
        let a = if amplitude_mm.is_nan() {
            0.0
        } else {
            within(amplitude_mm, 0.0, self.limits.amplitude_max_mm)
        };
        self.target_amplitude_mm = a;
        self.aborting = false;
    }

    /// Ramps the amplitude to zero at the abort rate.
    pub fn abort(&mut self) {
        self.target_amplitude_mm = 0.0;
        self.aborting = true;
    }

    /// Current (slewed) frequency, Hz.
    pub fn freq_hz(&self) -> f32 {
        freq_of(self.increment)
    }

    /// Target frequency, Hz.
    pub fn target_freq_hz(&self) -> f32 {
        freq_of(self.target_increment)
    }

    /// Current (ramped) amplitude, mm.
    pub fn amplitude_mm(&self) -> f32 {
        self.amplitude_mm
    }

    /// Target amplitude, mm.
    pub fn target_amplitude_mm(&self) -> f32 {
        self.target_amplitude_mm
    }

    /// Whether frequency and amplitude have reached their targets.
    pub fn settled(&self) -> bool {
        self.increment == self.target_increment && self.amplitude_mm == self.target_amplitude_mm
    }

    /// The phase accumulator (a full turn is 2³²).
    pub fn phase(&self) -> u32 {
        self.phase
    }

    /// Advances one sample: slews the frequency, ramps the amplitude, advances the phase.
    pub fn next_sample(&mut self) -> DriveSample {
        let (inc, target, step) = (
            self.increment,
            self.target_increment,
            self.max_increment_step,
        );
        self.increment = if inc < target {
            inc.saturating_add(step).min(target)
        } else {
            inc.saturating_sub(step).max(target)
        };
        let ramp = if self.aborting {
            self.abort_mm_per_sample
        } else {
            self.ramp_mm_per_sample
        };
        let (a, ta) = (self.amplitude_mm, self.target_amplitude_mm);
        self.amplitude_mm = if a < ta {
            (a + ramp).min(ta)
        } else {
            (a - ramp).max(ta)
        };
        let (phase, wrapped) = self.phase.overflowing_add(self.increment);
        self.phase = phase;
        let displacement_mm = self.amplitude_mm * sin_turn(phase);
        let code = libm::roundf(f32::from(DAC_MID) + displacement_mm * self.codes_per_mm);
        DriveSample {
            displacement_mm,
            // `as` saturates at 0 and 65535; clamp to the 12-bit range.
            code: (code as u16).min(crate::hal::ADC_MAX),
            cycle_start: wrapped,
        }
    }
}

/// Phase increment per sample of `freq_hz` (rounded).
fn increment_of(freq_hz: f32) -> u32 {
    libm::roundf(freq_hz / SAMPLE_RATE_HZ as f32 * TURN) as u32
}

/// Frequency (Hz) of a phase increment.
fn freq_of(increment: u32) -> f32 {
    increment as f32 / TURN * SAMPLE_RATE_HZ as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn generator() -> SineGenerator {
        SineGenerator::new(&Limits::default(), &DriveChain::default())
    }

    #[test]
    fn sin_turn_matches_libm() {
        let mut worst = 0.0f64;
        for k in 0..=100_000u64 {
            let phase = (k * 42_949) as u32;
            let exact = libm::sin(2.0 * core::f64::consts::PI * f64::from(phase) / 4_294_967_296.0);
            worst = worst.max((f64::from(sin_turn(phase)) - exact).abs());
        }
        assert!(worst < 3e-7, "{worst}");
        assert_eq!(sin_turn(0), 0.0);
        assert!((sin_turn(1 << 30) - 1.0).abs() < 3e-7);
        assert!((sin_turn(3 << 30) + 1.0).abs() < 3e-7);
    }

    #[test]
    fn frequency_is_exact_over_a_long_run() {
        // 3.659 Hz for 100 s at 10 kHz: the cycle count equals f·t to within one cycle, because
        // the phase is an integer accumulator (no f32 time drift).
        let mut g = generator();
        g.jump_freq_hz(3.659);
        g.set_amplitude_mm(0.89);
        let mut cycles = 0u32;
        for _ in 0..1_000_000 {
            cycles += u32::from(g.next_sample().cycle_start);
        }
        let expected = f64::from(g.freq_hz()) * 100.0;
        assert!(
            (f64::from(cycles) - expected).abs() <= 1.0,
            "{cycles} vs {expected}"
        );
        assert!((g.freq_hz() - 3.659).abs() < 1e-5);
    }

    #[test]
    fn frequency_change_is_phase_continuous_and_slew_limited() {
        let mut g = generator();
        g.jump_freq_hz(3.0);
        g.set_amplitude_mm(1.0);
        for _ in 0..20_000 {
            g.next_sample();
        }
        g.set_freq_hz(4.0);
        let mut prev = g.next_sample().displacement_mm;
        let mut prev_f = g.freq_hz();
        let mut n = 0;
        while !g.settled() {
            let s = g.next_sample();
            // Largest possible change of A sin between samples at ≤ 4 Hz: A·2π·f/fs.
            let bound = 1.0 * 2.0 * core::f32::consts::PI * 4.0 / SAMPLE_RATE_HZ as f32;
            assert!((s.displacement_mm - prev).abs() <= bound * 1.001);
            // Slew: 0.5 Hz/s = 5e-5 Hz per sample (increment rounding: 21 vs 21.47).
            assert!(g.freq_hz() - prev_f <= 5.1e-5 && g.freq_hz() >= prev_f);
            prev = s.displacement_mm;
            prev_f = g.freq_hz();
            n += 1;
        }
        // 1 Hz at 0.5 Hz/s ≈ 2 s (the rounded step makes it 2.2 % slower).
        assert!((20_000..=20_500).contains(&n), "{n}");
    }

    #[test]
    fn amplitude_ramps_and_stays_in_limits() {
        let mut g = generator();
        g.jump_freq_hz(100.0); // clamped to 30 Hz
        assert!((g.freq_hz() - 30.0).abs() < 1e-4);
        g.set_amplitude_mm(5.0); // clamped to 1.5 mm
        assert_eq!(g.target_amplitude_mm(), 1.5);
        // 0.5 mm/s: 1.5 mm in 3 s.
        for _ in 0..29_900 {
            g.next_sample();
        }
        assert!(g.amplitude_mm() < 1.5 && g.amplitude_mm() > 1.49);
        let mut lo = u16::MAX;
        let mut hi = 0;
        for _ in 0..10_000 {
            let s = g.next_sample();
            lo = lo.min(s.code);
            hi = hi.max(s.code);
        }
        // 1.5 mm · 1241.2 codes/mm = 1861.8 codes around 2048.
        assert!((i32::from(hi) - 3910).abs() <= 1 && (i32::from(lo) - 186).abs() <= 1);
        assert!(!g.jump_freq_hz(5.0), "no jump while driving");
        g.abort();
        // 4 mm/s: 1.5 mm in 0.375 s.
        for _ in 0..3_760 {
            g.next_sample();
        }
        assert_eq!(g.amplitude_mm(), 0.0);
        g.set_freq_hz(f32::NAN);
        g.set_amplitude_mm(f32::NAN);
        assert_eq!(g.target_amplitude_mm(), 0.0);
        assert!((g.target_freq_hz() - 30.0).abs() < 1e-4);
    }
}

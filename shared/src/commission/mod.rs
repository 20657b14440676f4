//! A rig that commissions itself: the board's own sequence from power-up to a model it can
//! run on, without a desktop — the shaker controllers' "system check" (background noise and
//! offsets, then identification, then a low-level verification) made for a vibro-impact rig.
//!
//! 1. [`Step::Sensor`]: the force at rest over [`REST_SAMPLES`] samples against the
//!    calibration: offset, noise, the ADC's rails, the sample rate ([`SensorCheck`]).
//! 2. [`Step::Drop`]: the operator releases the hammer from [`release_height_mm`] within
//!    [`DROP_WINDOW_S`] s; the capture records the impact train (it ends [`DROP_QUIET_S`] s
//!    after the last impact) and the board identifies the contact law and the suspension from
//!    it ([`crate::identify`]).
//! 3. [`Step::Select`]: the identified model becomes the active one and the board's selection
//!    ([`crate::control::predict`], the model task) gives its target, beside the target of the
//!    model the rig ran before.
//! 4. [`Step::Verify`]: the drive ramps to the target and tracks; after [`VERIFY_TRACK_S`] s in
//!    `track` the measured regime must be `1/1` and the peak force within
//!    [`VERIFY_FORCE_PCT`] % of the prediction; the drive stops.
//! 5. [`Step::Accept`]: the operator's `commission accept` stores the model in flash within
//!    [`ACCEPT_WINDOW_S`] s; anything else (`commission abort`, the window passing) keeps the
//!    model the rig ran before.
//!
//! A step that fails, a fault, an abort or a step that overruns its bound stops the sequence:
//! the drive ramps to zero (a latched fault waits for `clear`), the capture stops, and the
//! settings the rig ran before come back; nothing is stored unless accepted. Every step reports
//! a [`Progress`] record (the console's `!C` lines) with its verdict and numbers.
//!
//! The sequence is polled ([`Commission::poll`]) by the console service: the firmware's at
//! least once a second, the virtual rig's every millisecond; its clock is the controller's
//! sample count.

mod progress;
mod sensor;
mod sequence;

pub use progress::{
    EndReason, Numbered, Progress, SelectFailure, SelectOutcome, Step, VerifyFailure,
    VerifyOutcome, WaitFor,
};
pub use sensor::{MAX_NOISE_N, MAX_OFFSET_N, MAX_RATE_DEVIATION_PCT, SensorCheck, SensorFailure};
pub use sequence::{Commission, CommissionRefusal, Phase};

use crate::capture::Capture;
use crate::control::{Controller, SensorChain};
use crate::identify::{
    CaptureOnChain, DropIdentification, DropRecord, DropRefusal, SegmentForce, identify_drop,
};
use crate::store::{SaveError, SettingsStore};

/// Samples of the force at rest the sensor check measures (0.5 s at 10 kHz).
pub const REST_SAMPLES: u32 = 5_000;
/// Share of the sensor's range the model's first impact should reach from the release height
/// ([`release_height_mm`]): high enough for many impacts above the noise, low enough that a
/// contact twice as stiff as the model's stays off the rail (its peak is √2 higher).
pub const RELEASE_PEAK_SHARE: f32 = 0.4;
/// Lowest release height the prompt gives, mm.
pub const MIN_RELEASE_MM: f32 = 2.0;
/// Highest release height the prompt gives, mm.
pub const MAX_RELEASE_MM: f32 = 12.0;
/// The capture's trigger level over the noise measured at rest (7 σ: a false trigger in a
/// 10 s capture at 100 kHz has odds of about 10⁻³); never below
/// [`crate::capture::DEFAULT_LEVEL_N`].
pub const TRIGGER_SIGMAS: f32 = 7.0;
/// Time the operator has to release the hammer, s (the capture's length).
pub const DROP_WINDOW_S: f32 = 10.0;
/// Time without a new impact after which the drop's train is over and the capture ends, s
/// (the wire rig's impacts come every 0.23 s).
pub const DROP_QUIET_S: f32 = 2.0;
/// Longest wait for the board's selection, s.
pub const SELECT_TIMEOUT_S: f32 = 60.0;
/// Time in `track` before the verification measures, s.
pub const VERIFY_TRACK_S: f32 = 10.0;
/// Longest verification (ramp and tracking), s.
pub const VERIFY_TIMEOUT_S: f32 = 120.0;
/// Largest measured peak force's deviation from the prediction the verification accepts, %.
pub const VERIFY_FORCE_PCT: f32 = 10.0;
/// Longest ramp down after the verification, s.
pub const STOP_TIMEOUT_S: f32 = 60.0;
/// Time the operator has to accept, s.
pub const ACCEPT_WINDOW_S: f32 = 600.0;

/// The rig's pieces the sequence works with, each for the duration of one closure (the
/// firmware's RTIC resources, the virtual rig's fields); [`crate::console::RigAccess`] adds the
/// console's own.
pub trait RigPieces {
    /// Runs `f` on the controller.
    fn controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R;
    /// Runs `f` on the capture.
    fn capture<R>(&mut self, f: impl FnOnce(&mut Capture) -> R) -> R;
    /// Runs `f` on the settings store (flash: a `save` stalls the CPU on the board; the
    /// callers pause the controller's deadline checks around it).
    fn store<R>(&mut self, f: impl FnOnce(&mut dyn SettingsStore) -> R) -> R;
}

/// The board's identification of its capture, for the active model's mass and gap (the
/// draft's mass while one is open).
///
/// # Errors
/// [`DropRefusal`]: why the capture cannot fix the model.
pub fn identify_capture(rig: &mut impl RigPieces) -> Result<DropIdentification, DropRefusal> {
    let (mass_kg, gap_mm, sensor) = rig.controller(|c| {
        let mass = c.draft().map_or(c.model().0.mass_kg, |d| d.params.mass_kg);
        (mass, c.gap_mm(), c.config().sensor)
    });
    let mut rec = LockedCapture { rig, sensor };
    identify_drop(&mut rec, mass_kg as f32, gap_mm * 1e-3)
}

/// The active settings to the store, the controller's deadline checks paused while the flash
/// is written (the CPU stalls on the board's flash); the model is then the stored one. The
/// caller checks the drive is idle.
///
/// # Errors
/// [`SaveError`]: the store keeps its last good save and the model stays unsaved.
pub fn store_active(rig: &mut impl RigPieces) -> Result<u32, SaveError> {
    let settings = rig.controller(|c| {
        c.pause_sampling();
        c.settings()
    });
    let saved = rig.store(|s| s.save(&settings));
    rig.controller(|c| {
        c.resume_sampling();
        if saved.is_ok() {
            c.mark_stored();
        }
    });
    saved
}

/// The capture read through the rig's access, one short lock per segment (the firmware's
/// capture interrupt waits no longer than a copy).
struct LockedCapture<'r, R: RigPieces> {
    rig: &'r mut R,
    sensor: SensorChain,
}

impl<R: RigPieces> DropRecord for LockedCapture<'_, R> {
    fn segments(&mut self) -> usize {
        usize::from(self.rig.capture(|c| c.status().segments))
    }

    fn segment(&mut self, k: usize) -> Option<SegmentForce> {
        let sensor = self.sensor;
        self.rig.capture(|c| {
            CaptureOnChain {
                capture: c,
                sensor: &sensor,
            }
            .segment(k)
        })
    }

    fn samples(&mut self) -> u32 {
        self.rig.capture(|c| c.status().samples)
    }

    fn lost_samples(&mut self) -> u32 {
        self.rig.capture(|c| c.lost_samples())
    }

    fn level_n(&mut self) -> f32 {
        self.rig.capture(|c| c.status().level_n)
    }

    fn resolution_n(&mut self) -> f32 {
        self.sensor.code_step_n()
    }
}

/// The height to release the hammer from, mm, to 0.5 mm: the one whose first impact the
/// active model predicts at [`RELEASE_PEAK_SHARE`] of the sensor's largest force, within
/// [`MIN_RELEASE_MM`] ..= [`MAX_RELEASE_MM`]. Released at rest `h` above the surface at gap 0,
/// the suspension brings the hammer to it at `v = ω_n h`; the contact's undamped peak is
/// `m v ω_c` (`ω_c`: [`crate::model::ContactLaw::contact_omega`], at that speed). (The wire
/// rig's preset: 8.5 mm; the 170 mm beam's: 3.5 mm.)
pub fn release_height_mm(params: &crate::model::RigParams, max_force_n: f32) -> f32 {
    let omega_n = 2.0 * core::f64::consts::PI * params.natural_freq_hz();
    let target = f64::from(RELEASE_PEAK_SHARE * max_force_n);
    // v·ω_c(v) grows with v for every law: two fixed-point rounds from the linear guess.
    let mut h = f64::from(MAX_RELEASE_MM) * 1e-3;
    for _ in 0..3 {
        let v = omega_n * h;
        let peak = params.mass_kg * v * params.contact.contact_omega(params.mass_kg, v);
        if peak.is_nan() || peak <= 0.0 {
            break;
        }
        h *= target / peak;
    }
    let mm = libm::round(h * 2e3) / 2.0;
    crate::control::within(mm as f32, MIN_RELEASE_MM, MAX_RELEASE_MM)
}

/// Samples at the controller's rate in `seconds`.
fn samples_in(seconds: f32) -> u64 {
    (seconds * crate::control::SAMPLE_RATE_HZ as f32) as u64
}

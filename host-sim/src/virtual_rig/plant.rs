//! The virtual rig's plant: the hammer of `shared::model` (either suspension, any contact law)
//! in f64, driven by the cart motion that the drive chain makes of the controller's DAC codes,
//! integrated with its own settings, independently of the controller's f32 model.
//!
//! Drive chain, per sample interval `T_s = 100 µs` (all closed form, no extra state to
//! integrate): DAC code → volts around mid-scale (`(code − 2048) · 3.3 V / 4096`) → the DAC's
//! reconstruction filter as a first-order hold (linear from the previous code's voltage to this
//! one's over the interval: one sample of delay) → the power amplifier as a first-order lag
//! `τ v̇_a = v − v_a` → cart displacement `y = G v_a` (`G` = `cart_mm_per_v`). The hammer sees
//! the cart's acceleration `ÿ = G v̈_a` through [`Hammer::field_driven`].
//!
//! Hammer: fixed-step RK4 (`shared::integrate::rk4_step`) with `steps_per_sample` steps per
//! sample; a step whose switch-model region changes (arrival, departure) is redone as
//! `refine` shorter steps. The true contact force is recorded at every step end.

use anyhow::{Context, Result};
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use shared::control::config::DAC_MID;
use shared::integrate::rk4::rk4_step;
use shared::model::hammer::FieldEval;
use shared::model::{Hammer, Region, RigParams, SwitchBands};

use shared::control::SAMPLE_RATE_HZ;

/// The drive chain's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DriveChainSim {
    /// DAC full scale, V (3.3).
    pub dac_full_scale_v: f64,
    /// Power amplifier's first-order time constant, s (0.002: 2.6° of phase and 0.1 % of
    /// amplitude at 3.66 Hz).
    pub amp_tau_s: f64,
    /// Cart displacement per volt at the amplifier's output, mm/V (1.0, as the controller assumes).
    pub cart_mm_per_v: f64,
}

impl Default for DriveChainSim {
    fn default() -> Self {
        DriveChainSim {
            dac_full_scale_v: 3.3,
            amp_tau_s: 0.002,
            cart_mm_per_v: 1.0,
        }
    }
}

/// The plant's integration settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlantSettings {
    /// RK4 steps per sample (10: 10 µs, ~57 steps per 0.57 ms contact).
    pub steps_per_sample: u32,
    /// Steps a step is split into when the switch-model region changes within it (16).
    pub refine: u32,
    /// Switch-model bands.
    pub bands: SwitchBands,
}

impl Default for PlantSettings {
    fn default() -> Self {
        PlantSettings {
            steps_per_sample: 10,
            refine: 16,
            bands: SwitchBands::default(),
        }
    }
}

/// One completed contact episode of the plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueImpact {
    /// Time of the peak, s.
    pub t_s: f64,
    /// Peak contact force, N.
    pub peak_n: f64,
}

/// The plant.
#[derive(Debug, Clone)]
pub struct Plant {
    params: RigParams,
    gap_m: f64,
    bands: SwitchBands,
    hammer: Hammer<f64>,
    x: Vector2<f64>,
    t_s: f64,
    drive: DriveChainSim,
    settings: PlantSettings,
    /// Amplifier output, V.
    v_amp: f64,
    /// DAC voltage at the start of the current interval (first-order hold), V.
    v_prev: f64,
    approach: f64,
    region: Region,
    force_n: f64,
    episode_peak: Option<TrueImpact>,
    impacts: Vec<TrueImpact>,
    /// The contact force at the end of each step of the last sample interval, N.
    step_forces: Vec<f64>,
    /// exp(−h/τ), exp(−h/2τ) for the step `h`.
    decay: (f64, f64),
    /// The field at the current state and the cart acceleration it was evaluated with.
    last_eval: Option<(f64, FieldEval<f64>)>,
}

impl Plant {
    /// The hammer at rest relative to the cart, drive silent.
    ///
    /// # Errors
    /// Invalid rig parameters, gap or settings.
    pub fn new(
        params: &RigParams,
        gap_m: f64,
        drive: DriveChainSim,
        settings: PlantSettings,
    ) -> Result<Self> {
        anyhow::ensure!(
            (1..=1000).contains(&settings.steps_per_sample)
                && (1..=1000).contains(&settings.refine),
            "plant: steps_per_sample and refine must be in 1 ..= 1000"
        );
        anyhow::ensure!(
            drive.amp_tau_s.is_finite() && drive.amp_tau_s >= 1e-6 && drive.amp_tau_s <= 1.0,
            "drive.amp_tau_s must be in 1e-6 ..= 1 s"
        );
        anyhow::ensure!(
            drive.cart_mm_per_v.is_finite() && drive.cart_mm_per_v > 0.0,
            "drive.cart_mm_per_v must be > 0"
        );
        let hammer = compile(params, gap_m, &settings.bands)?;
        let x = hammer.state_from_relative(0.0, 0.0)?;
        let h = 1.0 / f64::from(SAMPLE_RATE_HZ) / f64::from(settings.steps_per_sample);
        Ok(Plant {
            params: *params,
            gap_m,
            bands: settings.bands,
            hammer,
            x,
            t_s: 0.0,
            drive,
            settings,
            v_amp: 0.0,
            v_prev: 0.0,
            approach: 0.0,
            region: Region::Free,
            force_n: 0.0,
            episode_peak: None,
            impacts: Vec::new(),
            step_forces: Vec::with_capacity(settings.steps_per_sample as usize),
            decay: decay(h, drive.amp_tau_s),
            last_eval: None,
        })
    }

    /// The rig parameters now (after any drift).
    pub fn params(&self) -> &RigParams {
        &self.params
    }

    /// Replaces the rig parameters (drift), keeping the hammer's relative position and velocity.
    ///
    /// # Errors
    /// Invalid parameters.
    pub fn set_params(&mut self, params: &RigParams) -> Result<()> {
        let (u, du) = self.hammer.relative(&self.x);
        let hammer = compile(params, self.gap_m, &self.bands)?;
        self.x = hammer.state_from_relative(u, du)?;
        self.hammer = hammer;
        self.last_eval = None;
        self.params = *params;
        Ok(())
    }

    /// Time, s.
    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    /// Contact force now, N.
    pub fn force_n(&self) -> f64 {
        self.force_n
    }

    /// Cart displacement now, m.
    pub fn cart_m(&self) -> f64 {
        self.drive.cart_mm_per_v * 1e-3 * self.v_amp
    }

    /// Relative displacement and velocity `(u, u̇)` now, m and m/s.
    pub fn relative(&self) -> (f64, f64) {
        self.hammer.relative(&self.x)
    }

    /// Contact episodes completed since the last call.
    pub fn take_impacts(&mut self) -> Vec<TrueImpact> {
        std::mem::take(&mut self.impacts)
    }

    /// The contact force at `n` equally spaced instants of the last sample interval (the
    /// `j`-th at `(j + 1)/n` of it), N: the steps' end forces, the step at or before each
    /// instant. With the default 10 steps per sample and `n = 10`, every step (100 kHz).
    pub fn forces_within_sample(&self, n: usize, out: &mut Vec<f64>) {
        out.clear();
        let m = self.step_forces.len();
        for j in 0..n {
            let i = ((j + 1) * m / n).max(1) - 1;
            out.push(self.step_forces.get(i).copied().unwrap_or(self.force_n));
        }
    }

    /// Releases the hammer at rest relative to the cart, `release_m` from the impact surface
    /// (`u = gap − release`): the drop test's start (thesis §3.3.2). An open contact episode
    /// ends.
    ///
    /// # Errors
    /// A start beyond the suspension's range.
    pub fn release(&mut self, release_m: f64) -> Result<()> {
        let x = self
            .hammer
            .state_from_relative(self.gap_m - release_m, 0.0)?;
        self.x = x;
        self.last_eval = None;
        self.region = Region::Free;
        self.force_n = 0.0;
        if let Some(p) = self.episode_peak.take() {
            self.impacts.push(p);
        }
        Ok(())
    }

    /// Advances one sample interval with the DAC at `dac_code`.
    pub fn advance(&mut self, dac_code: u16) {
        let v_code =
            (f64::from(dac_code) - f64::from(DAC_MID)) * self.drive.dac_full_scale_v / 4096.0;
        let ts = 1.0 / f64::from(SAMPLE_RATE_HZ);
        let tau = self.drive.amp_tau_s;
        let g = self.drive.cart_mm_per_v * 1e-3;
        // First-order hold: r(t) = r0 + s t over the interval; lag: closed form of τ v̇ = r − v.
        let (r0, s) = (self.v_prev, (v_code - self.v_prev) / ts);
        let c0 = self.v_amp - r0 + s * tau;
        // ÿ(t) = G c0 e^{−t/τ} / τ² with e = exp(−t/τ).
        let acc = |e: f64| g * c0 * e / (tau * tau);
        let n = self.settings.steps_per_sample;
        let h = ts / f64::from(n);
        let (dh, dh2) = self.decay;
        let mut e = 1.0;
        self.step_forces.clear();
        for k in 0..n {
            let t0 = self.t_s + f64::from(k) * h;
            self.step(t0, h, acc(e), acc(e * dh2), acc(e * dh), e, dh, &acc);
            self.step_forces.push(self.force_n);
            e *= dh;
        }
        self.t_s += ts;
        self.v_amp = r0 + s * ts - s * tau + c0 * e;
        self.v_prev = v_code;
    }

    /// One RK4 step of `h` from `t0` with the cart accelerations at its start, middle and end;
    /// redone as `refine` shorter steps when the switch-model region changes within it.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        t0: f64,
        h: f64,
        a0: f64,
        a_mid: f64,
        a_end: f64,
        e0: f64,
        dh: f64,
        acc: &impl Fn(f64) -> f64,
    ) {
        let (start_region, x1, end) = self.trial(h, a0, a_mid, a_end);
        if end.region == start_region || self.settings.refine <= 1 {
            self.commit(x1, t0 + h, a_end, end);
            return;
        }
        let m = self.settings.refine;
        let hr = h / f64::from(m);
        let dr = dh.powf(1.0 / f64::from(m));
        let dr2 = dr.sqrt();
        let mut e = e0;
        for j in 0..m {
            let a_end = acc(e * dr);
            let (_, x1, end) = self.trial(hr, acc(e), acc(e * dr2), a_end);
            self.commit(x1, t0 + f64::from(j + 1) * hr, a_end, end);
            e *= dr;
        }
    }

    /// An RK4 step of `h` from the current state (not committed): the start's region, the end
    /// state and the field there. The field at the start is the last committed end's when the
    /// cart acceleration is the same (consecutive steps within a sample).
    fn trial(
        &self,
        h: f64,
        a0: f64,
        a_mid: f64,
        a_end: f64,
    ) -> (Region, Vector2<f64>, FieldEval<f64>) {
        let approach = self.approach;
        let start = match self.last_eval {
            Some((a, e)) if a.to_bits() == a0.to_bits() => e,
            _ => self.hammer.field_driven(&self.x, a0, approach),
        };
        let f = |x: &Vector2<f64>, a: f64| self.hammer.field_driven(x, a, approach).dx;
        let x1 = rk4_step(&self.x, &start.dx, h, a_mid, a_end, f);
        (
            start.region,
            x1,
            self.hammer.field_driven(&x1, a_end, approach),
        )
    }

    fn commit(&mut self, x: Vector2<f64>, t: f64, a_end: f64, end: FieldEval<f64>) {
        self.last_eval = Some((a_end, end));
        if self.region == Region::Free && end.region != Region::Free {
            // Arrival: the approach speed (Lankarani–Nikravesh) is the rate at the surface; the
            // field at this state changes with it.
            self.approach = end.delta_dot.abs();
            self.last_eval = None;
        }
        self.x = x;
        self.region = end.region;
        self.force_n = end.force;
        if end.force > 0.0 {
            let peak = self.episode_peak.get_or_insert(TrueImpact {
                t_s: t,
                peak_n: 0.0,
            });
            if end.force > peak.peak_n {
                *peak = TrueImpact {
                    t_s: t,
                    peak_n: end.force,
                };
            }
        } else if end.region == Region::Free
            && let Some(p) = self.episode_peak.take()
        {
            self.impacts.push(p);
        }
    }
}

fn compile(params: &RigParams, gap_m: f64, bands: &SwitchBands) -> Result<Hammer<f64>> {
    // Ω only scales the harmonic drive, which field_driven does not use.
    Hammer::new(params, gap_m, params.omega_n(), bands).context("plant")
}

fn decay(h: f64, tau: f64) -> (f64, f64) {
    ((-h / tau).exp(), (-0.5 * h / tau).exp())
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared::model::RigId;

    /// A steady sine on the DAC: the cart follows with the first-order lag's amplitude
    /// `1/sqrt(1 + (Ωτ)²)` and phase, plus the hold's half-sample delay.
    #[test]
    fn drive_chain_gain_and_lag_match_the_first_order_response() {
        let p = RigId::Wires.preset();
        let mut plant = Plant::new(
            &p,
            0.015,
            DriveChainSim::default(),
            PlantSettings::default(),
        )
        .unwrap();
        let f = 20.0;
        let amp_v = 0.5;
        let n = 20_000; // 2 s
        let mut peak: f64 = 0.0;
        for k in 0..n {
            let t = f64::from(k) / 1e4;
            let v = amp_v * (2.0 * std::f64::consts::PI * f * t).sin();
            let code = (2048.0 + v * 4096.0 / 3.3).round() as u16;
            plant.advance(code);
            if k > n / 2 {
                peak = peak.max(plant.cart_m().abs());
            }
        }
        let w = 2.0 * std::f64::consts::PI * f;
        let expected = amp_v * 1e-3 / (1.0 + (w * 0.002).powi(2)).sqrt();
        assert!((peak / expected - 1.0).abs() < 2e-3, "{peak} vs {expected}");
    }
}

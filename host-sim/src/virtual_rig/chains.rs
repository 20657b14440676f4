//! The virtual rig's mocks of the firmware's hardware traits (`shared::hal`): the force sensor
//! chain (force → charge amplifier gain and offset → noise → 12-bit quantisation → rails), the
//! DAC, and a time base stepping at the sampling rate. Sensor faults are injected here.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use shared::control::{SAMPLE_PERIOD_US, config::DAC_MID};
use shared::hal::{ADC_MAX, DriveOutput, ForceSource, SampleError, TimeBase};

/// The sensing chain's parameters (the plant's truth; the controller has its own belief in
/// `ControllerConfig::sensor`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorChainSim {
    /// Charge amplifier gain, V/N (0.01).
    pub volts_per_n: f64,
    /// Output at zero force, V (0.2).
    pub offset_v: f64,
    /// White noise at the ADC input, V rms (0.002 ≈ 2.5 codes, 0.2 N).
    pub noise_v: f64,
    /// ADC full scale, V (3.3).
    pub adc_full_scale_v: f64,
    /// Seed of the noise stream (1; ChaCha8: the same stream on every machine).
    pub seed: u64,
}

impl Default for SensorChainSim {
    fn default() -> Self {
        SensorChainSim {
            volts_per_n: 0.01,
            offset_v: 0.2,
            noise_v: 0.002,
            adc_full_scale_v: 3.3,
            seed: 1,
        }
    }
}

/// A sensor fault in effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorState {
    /// Working.
    Ok,
    /// Cable open: the signal drops to the offset (noise remains).
    Open,
    /// Pinned at the upper (`true`) or lower rail.
    Stuck(bool),
}

/// The mock ADC: reads the force latched by the rig loop through the chain.
#[derive(Debug)]
pub struct MockAdc {
    chain: SensorChainSim,
    /// Force at the sensor for the next conversion, N (set by the rig loop).
    pub input_n: f64,
    /// Gain multiplier (the "gain change" fault), 1 when healthy.
    pub gain_factor: f64,
    /// Fault in effect.
    pub state: SensorState,
    rng: ChaCha8Rng,
    noise: Normal<f64>,
}

impl MockAdc {
    /// A healthy chain.
    ///
    /// # Errors
    /// A negative or non-finite noise level.
    pub fn new(chain: SensorChainSim) -> anyhow::Result<Self> {
        let noise = Normal::new(0.0, chain.noise_v)
            .map_err(|_| anyhow::anyhow!("sensor.noise_v must be ≥ 0 (got {})", chain.noise_v))?;
        anyhow::ensure!(
            chain.volts_per_n.is_finite() && chain.volts_per_n > 0.0,
            "sensor.volts_per_n must be > 0"
        );
        Ok(MockAdc {
            rng: ChaCha8Rng::seed_from_u64(chain.seed),
            chain,
            input_n: 0.0,
            gain_factor: 1.0,
            state: SensorState::Ok,
            noise,
        })
    }
}

impl ForceSource for MockAdc {
    fn read_code(&mut self) -> Result<u16, SampleError> {
        let c = &self.chain;
        let v = match self.state {
            SensorState::Stuck(high) => return Ok(if high { ADC_MAX } else { 0 }),
            SensorState::Open => c.offset_v,
            SensorState::Ok => c.offset_v + c.volts_per_n * self.gain_factor * self.input_n,
        } + self.noise.sample(&mut self.rng);
        let code = (v / c.adc_full_scale_v * 4096.0).round();
        Ok(code.clamp(0.0, f64::from(ADC_MAX)) as u16)
    }
}

/// The mock DAC: keeps the last code for the plant.
#[derive(Debug, Clone, Copy)]
pub struct MockDac {
    /// Last code written.
    pub code: u16,
}

impl Default for MockDac {
    fn default() -> Self {
        MockDac { code: DAC_MID }
    }
}

impl DriveOutput for MockDac {
    fn write_code(&mut self, code: u16) {
        self.code = code.min(ADC_MAX);
    }
}

/// The mock time base: sample count × the sampling period.
#[derive(Debug, Clone, Copy, Default)]
pub struct MockClock {
    /// Samples taken.
    pub samples: u64,
}

impl TimeBase for MockClock {
    fn now_us(&self) -> u64 {
        self.samples * u64::from(SAMPLE_PERIOD_US)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adc_chain_quantises_offsets_and_saturates() {
        let mut adc = MockAdc::new(SensorChainSim {
            noise_v: 0.0,
            ..SensorChainSim::default()
        })
        .unwrap();
        adc.input_n = 96.0; // 0.2 + 0.96 = 1.16 V = 1439.6 codes
        assert_eq!(adc.read_code(), Ok(1440));
        adc.input_n = 1000.0;
        assert_eq!(adc.read_code(), Ok(4095));
        adc.state = SensorState::Open;
        assert_eq!(adc.read_code(), Ok(248)); // 0.2 V
        adc.state = SensorState::Stuck(false);
        assert_eq!(adc.read_code(), Ok(0));
        // Noise: 0.002 V rms = 2.48 codes rms.
        let mut adc = MockAdc::new(SensorChainSim::default()).unwrap();
        let codes: Vec<f64> = (0..20_000)
            .map(|_| f64::from(adc.read_code().unwrap()))
            .collect();
        let mean = codes.iter().sum::<f64>() / codes.len() as f64;
        let rms =
            (codes.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / codes.len() as f64).sqrt();
        assert!((mean - 248.24).abs() < 0.1, "{mean}");
        assert!((rms - 2.50).abs() < 0.1, "{rms}");
    }
}

//! Firmware of the vibro-impact rig: an RTIC 2 application for the STM32F407 (Cortex-M4F).
//!
//! This first version logs, at start-up, the operating frequency that the `shared` selection
//! picks for the configured rig and gap (the same function `host-sim select` calls). The
//! shaker drive, impact sensing and tracking controller come with the controller issue.
//!
//! Build: `cargo fw-build`; flash and watch the defmt log: `cargo fw` (probe-rs).
//! On the host this crate compiles to a stub so that `cargo build --workspace` works.
#![cfg_attr(target_os = "none", no_std, no_main)]

/// Configuration of the rig this board drives.
pub mod config {
    use shared::model::RigId;

    /// The rig the firmware is configured for.
    pub const RIG: RigId = RigId::Wires;
    /// The gap set on the rig, m (field use: 0.0 mm).
    pub const GAP_M: f64 = 0.0;
}

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, dispatchers = [EXTI0])]
mod app {
    use defmt_rtt as _;
    use panic_probe as _;
    use shared::analysis::{SelectionSpec, SimSettings, select_sequential};

    use crate::config::{GAP_M, RIG};

    #[shared]
    struct Shared {}

    #[local]
    struct Local {}

    #[init]
    fn init(_cx: init::Context) -> (Shared, Local) {
        defmt::info!(
            "vibro-impact rig firmware: rig {}, gap {=f64} mm",
            RIG.name(),
            GAP_M * 1e3
        );
        if select_operating_point::spawn().is_err() {
            defmt::error!("could not start the selection task");
        }
        (Shared {}, Local {})
    }

    #[idle]
    fn idle(_cx: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// Runs the operating-frequency selection in f32 at the lowest priority and logs it.
    #[task(priority = 1)]
    async fn select_operating_point(_cx: select_operating_point::Context) {
        let params = RIG.preset();
        let spec = SelectionSpec::default();
        defmt::info!(
            "selecting the operating frequency ({=usize} frequencies per gap)...",
            spec.omega_ratio.len()
        );
        match select_sequential::<f32>(&params, GAP_M, &spec, &SimSettings::default()) {
            Ok(sel) => {
                defmt::info!(
                    "operating frequency {=f64} Hz (omega_ratio {=f64}), regime 1/1, F_i/mg {=f64}",
                    sel.best.freq_hz,
                    sel.best.omega_ratio,
                    sel.best.impact_force_mg
                );
                defmt::info!(
                    "1/1 band {=f64} .. {=f64} Hz, margin {=f64} % (frequency), +-{=f64} mm (gap), worst F_i/mg {=f64}",
                    sel.band_hz[0],
                    sel.band_hz[1],
                    sel.margin_freq_pct,
                    sel.margin_gap_mm,
                    sel.worst_impact_force_mg
                );
            }
            Err(e) => defmt::error!("selection failed: {}", defmt::Display2Format(&e)),
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "firmware for {} at {} mm gap: build it for the MCU with `cargo fw-build` (thumbv7em-none-eabihf)",
        config::RIG,
        config::GAP_M * 1e3
    );
}

//! Configuration of the rig this board drives at power-up (the console changes rig and gap).

use shared::console::Version;
use shared::model::RigId;

/// The rig at power-up.
pub const RIG: RigId = RigId::Wires;
/// The gap at power-up, mm (field use: 0.0 mm).
pub const GAP_MM: f32 = 0.0;
/// Core clock, Hz (also SysTick's clock, the monotonic's time base).
pub const SYSCLK_HZ: u32 = 168_000_000;
/// Independent watchdog timeout, ms.
pub const WATCHDOG_MS: u32 = 2_000;
/// The firmware's version (`id`).
pub const FIRMWARE_VERSION: Version = Version::of(env!("CARGO_PKG_VERSION"));
/// Samples per capture DMA block (half of the double buffer): 0.64 ms at 100 kHz.
pub const CAPTURE_BLOCK: usize = shared::capture_dma::BLOCK_LEN;
/// The console's baud rate (USART2, 8N1), Bd.
pub const CONSOLE_BAUD: u32 = 115_200;
/// The 8 MHz HSE comes from an external clock on OSC_IN (the ST-LINK's MCO on STM32F4DISCOVERY
/// boards that have no crystal X2 fitted), not from a crystal: RCC_CR.HSEBYP (RM0090 §7.2.1).
/// A board with its crystal (X2, 8 MHz) keeps `false`; with the wrong setting the HSE never
/// becomes ready and the board hangs in its clock set-up, before the first defmt line.
pub const HSE_BYPASS: bool = false;

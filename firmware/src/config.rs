//! Configuration of the board: what it runs when its store holds no usable settings (the
//! console changes the model, gap and calibration, and `save` keeps them in flash), its clocks,
//! and where the store lives.

use shared::console::Version;
use shared::model::RigId;

/// The rig preset at power-up when the store holds no usable settings (empty, corrupt, of
/// another version, or refused by the controller's checks).
pub const RIG: RigId = RigId::Wires;
/// The gap at power-up in that case, mm (field use: 0.0 mm).
pub const GAP_MM: f32 = 0.0;
/// The settings store: flash sectors 1 and 2 of the STM32F407 (16 KiB each, RM0090 §3.3
/// Table 5), from this address. The code starts after them (`memory.x`: `_stext`), the vector
/// table stays in sector 0. 16 KiB sectors erase in 250 ms typical, 500 ms at most at x32
/// parallelism (the STM32F407 datasheet, DS8626, table "Flash memory programming"): within the 2 s watchdog, unlike
/// the 128 KiB sectors (1 s typical, 2 s at most).
pub const STORE_ADDRESS: u32 = 0x0800_4000;
/// The store's sectors (erase units), RM0090 Table 5.
pub const STORE_SECTORS: [u8; 2] = [1, 2];
/// The store's size, bytes: two 16 KiB sectors.
pub const STORE_BYTES: u32 = shared::store::STORE_BYTES;
const _: () = assert!(STORE_BYTES == STORE_SECTORS.len() as u32 * 16 * 1024);
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

//! The rig board's clock tree and every number the board derives from it, computed here from
//! [`SYSCLK_HZ`], [`HSE_HZ`] and the sample rates, and checked at compile time against the
//! limits of the STM32F407's reference manual (RM0090 Rev 19) and datasheet (DS8626): a value
//! out of its range does not build. The board (`src/board_rig.rs`) writes these values or
//! hands them to stm32f4xx-hal, and `tests/tests/all/register_trace.rs` reads back what the image
//! writes.
//!
//! | clock | value | limit |
//! |---|---|---|
//! | HSE | 8 MHz | crystal 4–26 MHz, or an external clock with HSE bypass (§7.2.1) |
//! | PLL: VCO input HSE/M | 2 MHz | 1–2 MHz, 2 MHz to limit jitter (§7.3.2) |
//! | VCO output ×N | 336 MHz | 100–432 MHz, N 50–432 (§7.3.2) |
//! | SYSCLK = VCO/P, HCLK | 168 MHz | ≤ 168 MHz (§7.2) |
//! | 48 MHz clock = VCO/Q | 48 MHz | ≤ 48 MHz (§7.3.2) |
//! | PCLK1 (APB1) = HCLK/4 | 42 MHz | ≤ 42 MHz (§7.2) |
//! | PCLK2 (APB2) = HCLK/2 | 84 MHz | ≤ 84 MHz (§7.2) |
//! | TIM2/3/5 clock = 2 × PCLK1 | 84 MHz | ×2 when the APB1 prescaler is not 1 (§7.2) |
//! | ADCCLK = PCLK2/4 | 21 MHz | ≤ 36 MHz (DS8626 f_ADC; prescaler ADC_CCR.ADCPRE, §13.13.16) |
//! | flash wait states | 5 | 150 < HCLK ≤ 168 MHz at 2.7–3.6 V (§3.5.1, Table 10) |

use crate::config::{CONSOLE_BAUD, SYSCLK_HZ, WATCHDOG_MS};
use shared::capture::CAPTURE_RATE_HZ;
use shared::control::SAMPLE_RATE_HZ;

/// The external oscillator (the board's crystal, or the ST-LINK's MCO with bypass), Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// The PLL's input after its divider M, Hz (RM0090 §7.3.2: 1–2 MHz; 2 MHz limits jitter).
pub const VCO_IN_HZ: u32 = 2_000_000;
/// PLLM: HSE / M = [`VCO_IN_HZ`].
pub const PLL_M: u32 = HSE_HZ / VCO_IN_HZ;
/// PLLP: VCO / P = SYSCLK (2, 4, 6 or 8).
pub const PLL_P: u32 = 2;
/// The VCO's output, Hz (§7.3.2: 100–432 MHz).
pub const VCO_OUT_HZ: u32 = SYSCLK_HZ * PLL_P;
/// PLLN: VCO input × N = [`VCO_OUT_HZ`] (§7.3.2: 50–432).
pub const PLL_N: u32 = VCO_OUT_HZ / VCO_IN_HZ;
/// PLLQ: VCO / Q ≤ 48 MHz (USB OTG FS, SDIO, RNG; §7.3.2: 2–15).
pub const PLL_Q: u32 = VCO_OUT_HZ.div_ceil(48_000_000);
/// The AHB clock (HCLK = SYSCLK, prescaler 1), Hz.
pub const HCLK_HZ: u32 = SYSCLK_HZ;
/// APB1's prescaler (1, 2, 4, 8 or 16).
pub const APB1_DIV: u32 = 4;
/// APB2's prescaler.
pub const APB2_DIV: u32 = 2;
/// PCLK1 (APB1: USART2, DAC, TIM2/3/5, IWDG's bus), Hz (§7.2: ≤ 42 MHz).
pub const PCLK1_HZ: u32 = HCLK_HZ / APB1_DIV;
/// PCLK2 (APB2: ADC1/2), Hz (§7.2: ≤ 84 MHz).
pub const PCLK2_HZ: u32 = HCLK_HZ / APB2_DIV;
/// The clock of TIM2, TIM3 and TIM5 (APB1 timers), Hz: twice PCLK1 when APB1's prescaler is
/// not 1 (§7.2, "timer clock frequencies").
pub const APB1_TIMER_HZ: u32 = if APB1_DIV == 1 {
    PCLK1_HZ
} else {
    2 * PCLK1_HZ
};
/// Flash wait states at 2.7–3.6 V: one per started 30 MHz of HCLK (§3.5.1, Table 10).
pub const FLASH_WAIT_STATES: u32 = (HCLK_HZ - 1) / 30_000_000;

/// The ADC prescaler from PCLK2 (ADC_CCR.ADCPRE: 2, 4, 6 or 8; ADC1 and ADC2 share it).
pub const ADC_PRESCALER: u32 = 4;
/// ADCCLK, Hz (DS8626: f_ADC ≤ 36 MHz at VDDA 2.4–3.6 V).
pub const ADC_CLOCK_HZ: u32 = PCLK2_HZ / ADC_PRESCALER;
/// ADC sample time, ADC cycles (ADC_SMPRx = 001: 15 cycles, §13.13.4–5).
pub const ADC_SAMPLE_CYCLES: u32 = 15;
/// One 12-bit conversion: sample time + 12 cycles (§13.5: T_conv = sampling time + 12 cycles).
pub const ADC_CONVERSION_CYCLES: u32 = ADC_SAMPLE_CYCLES + 12;
/// One conversion, ns (1,286 ns at 21 MHz).
pub const ADC_CONVERSION_NS: u32 =
    ((ADC_CONVERSION_CYCLES as u64 * 1_000_000_000).div_ceil(ADC_CLOCK_HZ as u64)) as u32;

/// TIM2's auto-reload: one update (ADC1's trigger) per control sample, prescaler 1.
pub const TIM2_ARR: u32 = APB1_TIMER_HZ / SAMPLE_RATE_HZ - 1;
/// TIM3's auto-reload: one update (ADC2's trigger) per capture sample, prescaler 1.
pub const TIM3_ARR: u32 = APB1_TIMER_HZ / CAPTURE_RATE_HZ - 1;
/// TIM5's prescaler register: one count per µs (PSC + 1 timer clocks).
pub const TIM5_PSC: u32 = APB1_TIMER_HZ / 1_000_000 - 1;
/// TIM5's auto-reload: the whole 32-bit range, so that it wraps every 2³² µs, which is what
/// the 64-bit extension adds per wrap (`board_common::Micros64`).
pub const TIM5_ARR: u32 = u32::MAX;
/// A capture sample's timer phase against the control sample's, timer clocks: TIM3 is
/// started this far from TIM2's update, so that ADC1 and ADC2 never sample PA1 at the same
/// time (half a capture period; RM0090 §13.9 asks the same of ADCs converting one channel).
pub const TIM3_PHASE: u32 = TIM3_PERIOD / 2;
/// TIM3's period, timer clocks (ARR + 1).
pub const TIM3_PERIOD: u32 = APB1_TIMER_HZ / CAPTURE_RATE_HZ;
/// TIM2's period, timer clocks (ARR + 1).
pub const TIM2_PERIOD: u32 = APB1_TIMER_HZ / SAMPLE_RATE_HZ;

/// USART2's baud-rate register at 16× oversampling (OVER8 = 0): USARTDIV × 16 = PCLK1 / baud,
/// rounded (§30.3.4; mantissa in bits 15:4, fraction in 3:0).
pub const USART2_BRR: u32 = (PCLK1_HZ + CONSOLE_BAUD / 2) / CONSOLE_BAUD;
/// The baud rate that BRR gives, Bd.
pub const CONSOLE_BAUD_ACTUAL: u32 = PCLK1_HZ / USART2_BRR;
/// Its error against [`CONSOLE_BAUD`], ppm.
pub const CONSOLE_BAUD_ERROR_PPM: u32 =
    (CONSOLE_BAUD_ACTUAL.abs_diff(CONSOLE_BAUD) as u64 * 1_000_000 / CONSOLE_BAUD as u64) as u32;

/// The IWDG's clock (LSI, nominal), Hz (DS8626: 17–47 kHz).
pub const LSI_HZ: u32 = 32_000;
/// The IWDG's prescaler divider (IWDG_PR = 6: /256, §21.4.2).
pub const IWDG_DIVIDER: u32 = 256;
/// IWDG_PR for [`IWDG_DIVIDER`].
pub const IWDG_PR: u32 = 6;
/// IWDG_RLR: the reload for [`WATCHDOG_MS`] at the nominal LSI (§21.3, Table 107: timeout =
/// (RLR + 1) × divider / LSI).
pub const IWDG_RLR: u32 = WATCHDOG_MS * (LSI_HZ / 1000) / IWDG_DIVIDER - 1;

// The clock tree within RM0090's limits.
const _: () = assert!(HSE_HZ >= 4_000_000 && HSE_HZ <= 26_000_000);
const _: () = assert!(PLL_M >= 2 && PLL_M <= 63 && HSE_HZ == PLL_M * VCO_IN_HZ);
const _: () = assert!(VCO_IN_HZ >= 1_000_000 && VCO_IN_HZ <= 2_000_000);
const _: () = assert!(PLL_N >= 50 && PLL_N <= 432 && PLL_N * VCO_IN_HZ == VCO_OUT_HZ);
const _: () = assert!(VCO_OUT_HZ >= 100_000_000 && VCO_OUT_HZ <= 432_000_000);
const _: () = assert!(PLL_P == 2 || PLL_P == 4 || PLL_P == 6 || PLL_P == 8);
const _: () = assert!(PLL_Q >= 2 && PLL_Q <= 15 && VCO_OUT_HZ / PLL_Q <= 48_000_000);
const _: () = assert!(SYSCLK_HZ <= 168_000_000 && VCO_OUT_HZ / PLL_P == SYSCLK_HZ);
const _: () = assert!(PCLK1_HZ <= 42_000_000 && PCLK1_HZ * APB1_DIV == HCLK_HZ);
const _: () = assert!(PCLK2_HZ <= 84_000_000 && PCLK2_HZ * APB2_DIV == HCLK_HZ);
const _: () = assert!(FLASH_WAIT_STATES == 5);

// The ADCs: clock ≤ 36 MHz; a conversion well inside the capture's 10 µs and the control's
// 100 µs (one conversion per trigger, so ADC1 and ADC2 each finish long before their next).
const _: () =
    assert!(ADC_PRESCALER == 2 || ADC_PRESCALER == 4 || ADC_PRESCALER == 6 || ADC_PRESCALER == 8);
const _: () = assert!(ADC_CLOCK_HZ <= 36_000_000);
const _: () = assert!(ADC_CONVERSION_NS * CAPTURE_RATE_HZ < 1_000_000_000);
const _: () = assert!(ADC_CONVERSION_NS * SAMPLE_RATE_HZ < 1_000_000_000);

// The timers: exact rates (no rounding of the sample period), registers within their widths
// (TIM2 and TIM5 are 32-bit, TIM3 16-bit, prescalers 16-bit).
const _: () = assert!((TIM2_ARR + 1) * SAMPLE_RATE_HZ == APB1_TIMER_HZ);
const _: () = assert!((TIM3_ARR + 1) * CAPTURE_RATE_HZ == APB1_TIMER_HZ && TIM3_ARR <= 0xFFFF);
const _: () = assert!((TIM5_PSC + 1) * 1_000_000 == APB1_TIMER_HZ && TIM5_PSC <= 0xFFFF);
// ADC1's trigger period is a whole number of ADC2's, so the phase offset holds.
const _: () = assert!(TIM2_PERIOD.is_multiple_of(TIM3_PERIOD) && TIM3_PERIOD == TIM3_ARR + 1);
// The two samplings of PA1 (15 ADC cycles each) never overlap.
const _: () = assert!(
    (TIM3_PHASE as u64) * (ADC_CLOCK_HZ as u64)
        > (ADC_SAMPLE_CYCLES as u64) * (APB1_TIMER_HZ as u64)
);

// The console: BRR in range, the baud rate within 1 % (the receiver tolerates about 3 %).
const _: () = assert!(USART2_BRR >= 16 && USART2_BRR <= 0xFFFF);
const _: () = assert!(CONSOLE_BAUD_ERROR_PPM < 10_000);

// The watchdog: the reload fits 12 bits and gives the timeout at the nominal LSI.
const _: () = assert!(IWDG_RLR <= 0xFFF);
const _: () = assert!((IWDG_RLR + 1) * IWDG_DIVIDER * 1000 / LSI_HZ == WATCHDOG_MS);

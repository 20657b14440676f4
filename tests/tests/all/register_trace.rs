//! The rig image's register writes against RM0090 Rev 19 (the STM32F407's reference manual):
//! `firmware/tools/register_trace.py` runs the rig image (`firmware`, the board QEMU cannot run)
//! in unicorn from its reset handler through `init` to its idle loop, feeds it interrupts (ADC1
//! ends of conversion, console lines on USART2, a full capture DMA block, a DMA transfer error,
//! an ADC1 overrun) and prints every peripheral register access. These tests read that trace
//! and check the values and the order the manual requires; the expected values are computed
//! here from the manual's field layouts and limits, not taken from the firmware's constants.
//!
//! Needs the image (`cargo fw-build`) and python3 with unicorn and pyelftools (`pip install
//! unicorn pyelftools`; `.ci/run` installs them and runs these tests): ignored unless asked for
//! (`cargo test -p e2e-tests --test all register_trace:: -- --include-ignored`), where a missing tool
//! fails them. The trace is run once per image and kept beside it (`register-trace-HASH.txt`),
//! so that the tests, one process each under `cargo nextest`, read it instead of running it
//! again. `REGISTER_TRACE_ELF=path` runs them on another image (e.g. an older build, to see what
//! they catch).

use std::collections::BTreeMap;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

// Register addresses (RM0090 §2.3 Table 1 for the bases; each register's section for its offset).
const RCC_CR: u32 = 0x4002_3800; // §7.3.1
const RCC_PLLCFGR: u32 = 0x4002_3804; // §7.3.2
const RCC_CFGR: u32 = 0x4002_3808; // §7.3.3
const RCC_AHB1ENR: u32 = 0x4002_3830; // §7.3.10
const RCC_APB1ENR: u32 = 0x4002_3840; // §7.3.13
const RCC_APB2ENR: u32 = 0x4002_3844; // §7.3.14
const FLASH_ACR: u32 = 0x4002_3C00; // §3.9.1
const FLASH_KEYR: u32 = 0x4002_3C04; // §3.9.2
const FLASH_SR: u32 = 0x4002_3C0C; // §3.9.4
const FLASH_CR: u32 = 0x4002_3C10; // §3.9.5
const GPIOA_MODER: u32 = 0x4002_0000; // §8.4.1
const GPIOA_AFRL: u32 = 0x4002_0020; // §8.4.9
const ADC1: u32 = 0x4001_2000; // §13.13
const ADC2: u32 = 0x4001_2100;
const ADC_SR: u32 = 0x00;
const ADC_CR1: u32 = 0x04;
const ADC_CR2: u32 = 0x08;
const ADC_SMPR2: u32 = 0x10;
const ADC_SQR3: u32 = 0x34;
const ADC_DR: u32 = 0x4C;
const ADC_CCR: u32 = 0x4001_2304; // §13.13.16
const DAC_CR: u32 = 0x4000_7400; // §14.5.1
const DAC_DHR12R1: u32 = 0x4000_7408; // §14.5.3
const TIM2: u32 = 0x4000_0000; // §18.4
const TIM3: u32 = 0x4000_0400;
const TIM5: u32 = 0x4000_0C00;
const TIM_CR1: u32 = 0x00;
const TIM_CR2: u32 = 0x04;
const TIM_EGR: u32 = 0x14;
const TIM_PSC: u32 = 0x28;
const TIM_ARR: u32 = 0x2C;
const DMA2_LIFCR: u32 = 0x4002_6408; // §10.5.3
const DMA2_S2CR: u32 = 0x4002_6440; // §10.5.5: 0x10 + 0x18 × 2
const DMA2_S2NDTR: u32 = 0x4002_6444;
const DMA2_S2PAR: u32 = 0x4002_6448;
const DMA2_S2M0AR: u32 = 0x4002_644C;
const DMA2_S2M1AR: u32 = 0x4002_6450;
const USART2_BRR: u32 = 0x4000_4408; // §30.6.3
const USART2_CR1: u32 = 0x4000_440C; // §30.6.4
const IWDG_KR: u32 = 0x4000_3000; // §21.4.1
const IWDG_PR: u32 = 0x4000_3004;
const IWDG_RLR: u32 = 0x4000_3008;
const DBGMCU_APB1_FZ: u32 = 0xE004_2008; // §38.16.4
const NVIC_ISER: u32 = 0xE000_E100; // PM0214 §4.3
const NVIC_IPR: u32 = 0xE000_E400;

// Interrupt numbers (RM0090 §12.2, Table 61).
const IRQ_EXTI1: u32 = 7;
const IRQ_ADC: u32 = 18;
const IRQ_USART2: u32 = 38;
const IRQ_DMA2_STREAM2: u32 = 58;

/// The flash's main memory (§2.3 Table 1, §3.3 Table 5: one 1 MiB bank).
const FLASH_MEMORY: std::ops::Range<u32> = 0x0800_0000..0x0810_0000;
/// The settings store: 32 KiB from 0x0800_4000 (docs/operator.md; `memory.x` keeps it free of
/// the image). Which sectors that is comes from the manual's sector table.
const STORE: std::ops::Range<u32> = 0x0800_4000..0x0800_C000;
/// FLASH_KEYR's unlock sequence (§3.6.1).
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
/// FLASH_CR's bits (§3.9.5): PG 0, SER 1, MER 2, SNB 6:3, PSIZE 9:8, STRT 16, LOCK 31.
const CR_PG: u32 = 0;
const CR_SER: u32 = 1;
const CR_MER: u32 = 2;
const CR_STRT: u32 = 16;
const CR_LOCK: u32 = 31;
/// FLASH_SR's bits (§3.9.4): EOP 0, OPERR 1, WRPERR 4, PGAERR 5, PGPERR 6, PGSERR 7 (all
/// rc_w1), BSY 16.
const SR_WRPERR: u32 = 4;
const SR_BSY: u32 = 16;
const SR_ERRORS: u32 = (1 << 1) | (1 << 4) | (1 << 5) | (1 << 6) | (1 << 7);
/// PSIZE for VDD 2.7–3.6 V (the board's 3.3 V): x32 (§3.6.2, Table 16: 00 x8, 01 x16,
/// 10 x32, 11 x64).
const PSIZE_X32: u32 = 0b10;

/// The clocks the manual allows at most, Hz (§7.2; DS8626 for the ADC).
const SYSCLK_MAX: f64 = 168e6;
const PCLK1_MAX: f64 = 42e6;
const PCLK2_MAX: f64 = 84e6;
const ADCCLK_MAX: f64 = 36e6;
/// The board's crystal, Hz.
const HSE: f64 = 8e6;

#[derive(Debug, Clone)]
enum Ev {
    /// A write: address, value.
    W(u32, u32),
    /// A read: address, the value read.
    R(u32, u32),
    /// A CPU store into the flash memory (programming, §3.6.4): address, size in bytes.
    F(u32, u32),
    /// A bit set or cleared through its bit-band alias: address, bit, value.
    B(u32, u32, bool),
    /// A marker: kind, text.
    M(String, String),
}

struct Trace {
    events: Vec<Ev>,
}

fn hex(s: &str) -> u32 {
    u32::from_str_radix(s.trim_start_matches("0x"), 16).unwrap()
}

impl Trace {
    fn parse(text: &str) -> Trace {
        let mut events = Vec::new();
        for line in text.lines() {
            let f: Vec<&str> = line.splitn(4, ' ').collect();
            let ev = match f[0] {
                "W" | "R" | "B" => {
                    let w: Vec<&str> = line.split_whitespace().collect();
                    match w[0] {
                        "W" if FLASH_MEMORY.contains(&hex(w[2])) => {
                            Ev::F(hex(w[2]), w[3].parse().unwrap())
                        }
                        "W" => Ev::W(hex(w[2]), hex(w[4])),
                        "R" => Ev::R(hex(w[2]), hex(w[4])),
                        _ => Ev::B(hex(w[2]), w[3].parse().unwrap(), w[4] == "1"),
                    }
                }
                "M" => Ev::M(
                    f.get(2).unwrap_or(&"").to_string(),
                    f.get(3).unwrap_or(&"").to_string(),
                ),
                _ => panic!("unreadable trace line: {line}"),
            };
            events.push(ev);
        }
        Trace { events }
    }

    /// Index of the marker `kind text`.
    fn marker(&self, kind: &str, text: &str) -> usize {
        self.events
            .iter()
            .position(|e| matches!(e, Ev::M(k, t) if k == kind && t == text))
            .unwrap_or_else(|| panic!("no marker `{kind} {text}` in the trace"))
    }

    /// The events of phase `name` (to the next phase).
    fn phase(&self, name: &str) -> &[Ev] {
        let start = self.marker("phase", name);
        let end = self.events[start + 1..]
            .iter()
            .position(|e| matches!(e, Ev::M(k, _) if k == "phase" || k == "done"))
            .map_or(self.events.len(), |i| start + 1 + i);
        &self.events[start..end]
    }

    /// The start-up: reset to idle.
    fn boot(&self) -> &[Ev] {
        &self.events[..self.marker("idle", "")]
    }
}

impl Trace {
    /// The event indices of phase `name` (to the next phase).
    fn phase_range(&self, name: &str) -> std::ops::Range<usize> {
        let ph = self.phase(name);
        let start = self.marker("phase", name);
        start..start + ph.len()
    }
}

/// The flash's sectors (§3.3, Table 5): 4 × 16 KiB, 1 × 64 KiB, 7 × 128 KiB from 0x0800_0000.
fn sector(n: u32) -> std::ops::Range<u32> {
    let size = |k: u32| match k {
        0..=3 => 16 * 1024,
        4 => 64 * 1024,
        _ => 128 * 1024,
    };
    let base = FLASH_MEMORY.start + (0..n).map(size).sum::<u32>();
    base..base + size(n)
}

/// The sectors inside the store.
fn store_sectors() -> Vec<u32> {
    (0..12)
        .filter(|&n| STORE.start <= sector(n).start && sector(n).end <= STORE.end)
        .collect()
}

/// An erase or a word programmed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FlashOpKind {
    /// A sector erase (SER, SNB, STRT; §3.6.3).
    Erase { snb: u32 },
    /// A CPU store into the flash with PG set (§3.6.4).
    Program { addr: u32 },
}

#[derive(Debug, Clone)]
struct FlashOp {
    kind: FlashOpKind,
    /// Its event index.
    at: usize,
    /// Whether FLASH_SR was read with BSY clear after it, before anything else touched the
    /// flash interface.
    waited: bool,
}

/// The flash interface's use over the whole trace, walked as RM0090 §3.6 describes it; each
/// rule broken is a `violation` tagged with the rule (`unlock:`, `keys:`, `psize:`, `sector:`,
/// `strt:`, `program:`, `bsy:`, `relock:`, `errors:`).
#[derive(Debug, Default)]
struct FlashWalk {
    ops: Vec<FlashOp>,
    /// Event indices of the KEY2 writes that unlocked FLASH_CR.
    unlocks: Vec<usize>,
    /// Event indices of the FLASH_CR writes that set LOCK.
    locks: Vec<usize>,
    /// FLASH_SR reads with error flags: index, flags.
    error_reads: Vec<(usize, u32)>,
    /// FLASH_SR writes that cleared error flags: index, the flags cleared.
    error_clears: Vec<(usize, u32)>,
    violations: Vec<String>,
}

impl FlashWalk {
    fn broken(&self, rule: &str) -> Vec<&String> {
        self.violations
            .iter()
            .filter(|v| v.starts_with(rule))
            .collect()
    }

    fn ops_in(&self, r: &std::ops::Range<usize>) -> Vec<&FlashOp> {
        self.ops.iter().filter(|o| r.contains(&o.at)).collect()
    }
}

fn flash_walk(evs: &[Ev]) -> FlashWalk {
    let mut w = FlashWalk::default();
    let store = store_sectors();
    // The reset state (§3.9.5: FLASH_CR = 0x8000_0000, locked).
    let mut locked = true;
    let mut keys = 0;
    let mut cr = 1 << CR_LOCK;
    let mut busy: Option<usize> = None;
    let mut errors = 0;
    for (i, e) in evs.iter().enumerate() {
        let busy_check = |w: &mut FlashWalk, what: &str| {
            if let Some(k) = busy {
                w.violations.push(format!(
                    "bsy: {what} at event {i} while the operation at event {} is busy",
                    w.ops[k].at
                ));
            }
        };
        match e {
            Ev::M(k, _) if k == "power-up" => {
                locked = true;
                keys = 0;
                cr = 1 << CR_LOCK;
                busy = None;
                errors = 0;
            }
            Ev::M(k, t) if k == "reply" => {
                if !locked {
                    w.violations
                        .push(format!("relock: unlocked at the reply `{t}` (event {i})"));
                }
                busy_check(&mut w, "a reply");
                if errors != 0 {
                    w.violations.push(format!(
                        "errors: FLASH_SR error flags 0x{errors:x} left set at the reply `{t}`"
                    ));
                }
            }
            Ev::W(a, v) if *a == FLASH_KEYR => {
                busy_check(&mut w, "a FLASH_KEYR write");
                if !locked {
                    w.violations.push(format!(
                        "keys: 0x{v:08x} written at event {i} while unlocked (a bus error)"
                    ));
                } else {
                    match (keys, *v) {
                        (0, KEY1) => keys = 1,
                        (1, KEY2) => {
                            keys = 0;
                            locked = false;
                            w.unlocks.push(i);
                        }
                        _ => {
                            keys = 0;
                            w.violations.push(format!(
                                "keys: 0x{v:08x} out of sequence at event {i} (FLASH_CR locked until reset)"
                            ));
                        }
                    }
                }
            }
            Ev::W(a, v) if *a == FLASH_CR => {
                let v = *v;
                if locked {
                    w.violations.push(format!(
                        "unlock: FLASH_CR 0x{v:08x} written locked at event {i}"
                    ));
                }
                busy_check(&mut w, "a FLASH_CR write");
                if errors != 0 {
                    w.violations.push(format!(
                        "errors: FLASH_CR written at event {i} with FLASH_SR flags 0x{errors:x} set"
                    ));
                }
                let (pg, ser, strt) = (bit(v, CR_PG), bit(v, CR_SER), bit(v, CR_STRT));
                let snb = field(v, 6, 3);
                if (pg || ser) && field(v, 9, 8) != PSIZE_X32 {
                    w.violations.push(format!(
                        "psize: FLASH_CR 0x{v:08x} at event {i}: PSIZE {:02b}, not x32",
                        field(v, 9, 8)
                    ));
                }
                if bit(v, CR_MER) {
                    w.violations
                        .push(format!("sector: mass erase (MER) at event {i}"));
                }
                if pg && ser {
                    w.violations
                        .push(format!("program: PG and SER at once at event {i}"));
                }
                if ser && !store.contains(&snb) {
                    w.violations.push(format!(
                        "sector: SNB {snb} selected at event {i}: not a store sector {store:?}"
                    ));
                }
                if strt {
                    if !ser {
                        w.violations
                            .push(format!("strt: STRT without SER at event {i}"));
                    } else if !(bit(cr, CR_SER) && field(cr, 6, 3) == snb) {
                        w.violations.push(format!(
                            "strt: STRT at event {i} not after SER and SNB {snb} were set"
                        ));
                    }
                    busy = Some(w.ops.len());
                    w.ops.push(FlashOp {
                        kind: FlashOpKind::Erase { snb },
                        at: i,
                        waited: false,
                    });
                }
                if bit(v, CR_LOCK) {
                    locked = true;
                    w.locks.push(i);
                }
                cr = v;
            }
            Ev::F(a, size) => {
                let a = *a;
                if locked {
                    w.violations.push(format!(
                        "unlock: flash 0x{a:08x} written locked at event {i}"
                    ));
                }
                busy_check(&mut w, "a flash write");
                if !bit(cr, CR_PG) || bit(cr, CR_SER) {
                    w.violations.push(format!(
                        "program: 0x{a:08x} written at event {i} with FLASH_CR 0x{cr:08x} (no PG)"
                    ));
                }
                if field(cr, 9, 8) != PSIZE_X32 {
                    w.violations.push(format!(
                        "psize: 0x{a:08x} programmed at event {i} with PSIZE {:02b}",
                        field(cr, 9, 8)
                    ));
                }
                if *size != 4 || a % 4 != 0 {
                    w.violations.push(format!(
                        "program: {size} bytes at 0x{a:08x} (event {i}): not an aligned word"
                    ));
                }
                if !STORE.contains(&a) {
                    w.violations.push(format!(
                        "program: 0x{a:08x} (event {i}) outside the store {STORE:x?}"
                    ));
                }
                busy = Some(w.ops.len());
                w.ops.push(FlashOp {
                    kind: FlashOpKind::Program { addr: a },
                    at: i,
                    waited: false,
                });
            }
            Ev::R(a, v) if *a == FLASH_SR => {
                if !bit(*v, SR_BSY)
                    && let Some(k) = busy.take()
                {
                    w.ops[k].waited = true;
                }
                if v & SR_ERRORS != 0 {
                    w.error_reads.push((i, v & SR_ERRORS));
                }
                errors |= v & SR_ERRORS;
            }
            Ev::W(a, v) if *a == FLASH_SR => {
                // rc_w1 (§3.9.4): a 1 clears, a 0 leaves.
                if errors & v != 0 {
                    w.error_clears.push((i, errors & v));
                }
                errors &= !v;
            }
            _ => {}
        }
    }
    w
}

/// The flash walk of the whole trace.
fn flash() -> &'static FlashWalk {
    static WALK: OnceLock<FlashWalk> = OnceLock::new();
    WALK.get_or_init(|| flash_walk(&trace().events))
}

/// The reply in `evs` that starts with `prefix`.
fn reply_starting<'a>(evs: &'a [Ev], prefix: &str) -> &'a str {
    replies(evs)
        .into_iter()
        .find(|r| r.starts_with(prefix))
        .unwrap_or_else(|| panic!("no reply `{prefix}…` in {:?}", replies(evs)))
}

/// The value of `key=` in a reply.
fn value_of<'a>(reply: &'a str, key: &str) -> &'a str {
    reply
        .split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .unwrap_or_else(|| panic!("no {key}= in `{reply}`"))
}

/// Writes to `addr` in `evs`, in order.
fn writes(evs: &[Ev], addr: u32) -> Vec<u32> {
    evs.iter()
        .filter_map(|e| match e {
            Ev::W(a, v) if *a == addr => Some(*v),
            _ => None,
        })
        .collect()
}

/// The last value written to `addr` during start-up.
fn last(t: &Trace, addr: u32) -> u32 {
    *writes(t.boot(), addr)
        .last()
        .unwrap_or_else(|| panic!("0x{addr:08x} never written during start-up"))
}

/// Index of the first event in `evs` that `f` picks.
fn first(evs: &[Ev], what: &str, f: impl Fn(&Ev) -> bool) -> usize {
    evs.iter()
        .position(f)
        .unwrap_or_else(|| panic!("no {what} in the trace"))
}

fn field(v: u32, hi: u32, lo: u32) -> u32 {
    (v >> lo) & ((1 << (hi - lo + 1)) - 1)
}

fn bit(v: u32, n: u32) -> bool {
    v >> n & 1 == 1
}

/// Replies printed on the console in `evs`.
fn replies(evs: &[Ev]) -> Vec<&str> {
    evs.iter()
        .filter_map(|e| match e {
            Ev::M(k, t) if k == "reply" => Some(t.as_str()),
            _ => None,
        })
        .collect()
}

/// Interrupts delivered in `evs`.
fn irqs(evs: &[Ev]) -> Vec<u32> {
    evs.iter()
        .filter_map(|e| match e {
            Ev::M(k, t) if k == "irq" => t.split_whitespace().next()?.parse().ok(),
            _ => None,
        })
        .collect()
}

fn rig_image() -> PathBuf {
    std::env::var_os("REGISTER_TRACE_ELF")
        .map(PathBuf::from)
        .unwrap_or_else(|| e2e_tests::firmware_image("firmware"))
}

/// The trace of the rig image: run once per image and script (the file `register-trace-HASH.txt`
/// beside the image, `HASH` of both), and read from that file after.
///
/// # Panics
/// Without the image or python's unicorn and pyelftools, saying which.
fn trace() -> &'static Trace {
    static TRACE: OnceLock<Trace> = OnceLock::new();
    TRACE.get_or_init(|| {
        let elf = rig_image();
        let script =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../firmware/tools/register_trace.py");
        let python = Command::new("python3")
            .args(["-c", "import unicorn, elftools"])
            .output();
        let python_ok = python.as_ref().is_ok_and(|o| o.status.success());
        assert!(
            elf.exists() && python_ok,
            "the register trace needs {} (cargo fw-build) and python3 with unicorn and \
             pyelftools (pip install unicorn pyelftools) (found: image {}, python modules {python_ok})",
            elf.display(),
            elf.exists()
        );
        let mut key = DefaultHasher::new();
        std::fs::read(&elf).unwrap().hash(&mut key);
        std::fs::read(&script).unwrap().hash(&mut key);
        let kept = elf.with_file_name(format!("register-trace-{:016x}.txt", key.finish()));
        if let Ok(text) = std::fs::read_to_string(&kept) {
            return Trace::parse(&text);
        }
        let out = Command::new("python3")
            .arg(&script)
            .arg(&elf)
            .output()
            .expect("run register_trace.py");
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "register_trace.py failed ({}): {}\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr),
            text.lines().rev().take(40).collect::<Vec<_>>().join("\n")
        );
        // Whole or not at all: written aside, then renamed (another test may be writing the
        // same trace).
        let tmp = kept.with_extension(format!("{}.tmp", std::process::id()));
        if std::fs::write(&tmp, &text).is_ok() {
            let _ = std::fs::rename(&tmp, &kept);
        }
        Trace::parse(&text)
    })
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_clock_tree_is_168_mhz_from_the_8_mhz_crystal_within_rm0090s_limits() {
    let t = trace();
    // RCC_PLLCFGR (§7.3.2): PLLM 5:0, PLLN 14:6, PLLP 17:16 (00 = /2, 01 = /4 …), PLLSRC 22
    // (1 = HSE), PLLQ 27:24.
    let pll = last(t, RCC_PLLCFGR);
    let (m, n, p, q) = (
        f64::from(field(pll, 5, 0)),
        f64::from(field(pll, 14, 6)),
        f64::from(2 * (field(pll, 17, 16) + 1)),
        f64::from(field(pll, 27, 24)),
    );
    assert!(bit(pll, 22), "PLL source not HSE: 0x{pll:08x}");
    let vco_in = HSE / m;
    let vco_out = vco_in * n;
    let sysclk = vco_out / p;
    assert!((1e6..=2e6).contains(&vco_in), "VCO input {vco_in} Hz");
    assert!(
        (100e6..=432e6).contains(&vco_out),
        "VCO output {vco_out} Hz"
    );
    assert_eq!(sysclk, SYSCLK_MAX, "SYSCLK from PLLCFGR 0x{pll:08x}");
    assert!(vco_out / q <= 48e6, "PLL48CK {} Hz", vco_out / q);

    // RCC_CFGR (§7.3.3): SW 1:0 = 10 (PLL), HPRE 7:4 = 0xxx (/1), PPRE1 12:10, PPRE2 15:13
    // (0xx = /1, 100 = /2, 101 = /4, 110 = /8, 111 = /16).
    let cfgr = last(t, RCC_CFGR);
    let apb = |bits: u32| {
        if bits < 4 {
            1.0
        } else {
            f64::from(1 << (bits - 3))
        }
    };
    assert_eq!(
        field(cfgr, 1, 0),
        0b10,
        "SYSCLK not from the PLL: 0x{cfgr:08x}"
    );
    assert!(field(cfgr, 7, 4) < 8, "AHB prescaler: 0x{cfgr:08x}");
    let pclk1 = sysclk / apb(field(cfgr, 12, 10));
    let pclk2 = sysclk / apb(field(cfgr, 15, 13));
    assert!(
        pclk1 <= PCLK1_MAX && pclk2 <= PCLK2_MAX,
        "PCLK1 {pclk1}, PCLK2 {pclk2}"
    );
    assert_eq!((pclk1, pclk2), (42e6, 84e6));

    // RCC_CR (§7.3.1): HSEON (16) on, HSEBYP (18) off: a crystal; PLLON (24).
    let cr = last(t, RCC_CR);
    assert!(
        bit(cr, 16) && !bit(cr, 18) && bit(cr, 24),
        "RCC_CR 0x{cr:08x}"
    );

    // FLASH_ACR (§3.9.1): 5 wait states for 150 < HCLK ≤ 168 MHz at 2.7–3.6 V (§3.5.1,
    // Table 10), written before SYSCLK switches to the PLL; prefetch, I- and D-cache on.
    let acr = last(t, FLASH_ACR);
    assert_eq!(field(acr, 2, 0), 5, "FLASH_ACR 0x{acr:08x}");
    assert!(
        bit(acr, 8) && bit(acr, 9) && bit(acr, 10),
        "FLASH_ACR 0x{acr:08x}"
    );
    let boot = t.boot();
    let acr_at = first(
        boot,
        "FLASH_ACR write",
        |e| matches!(e, Ev::W(a, v) if *a == FLASH_ACR && v & 7 == 5),
    );
    let sw_at = first(
        boot,
        "switch to the PLL",
        |e| matches!(e, Ev::W(a, v) if *a == RCC_CFGR && v & 3 == 2),
    );
    assert!(
        acr_at < sw_at,
        "the wait states come after the switch to 168 MHz"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn every_peripheral_is_clocked_before_its_registers_are_written() {
    let t = trace();
    let boot = t.boot();
    // (enable register, bit, the peripheral's registers, name): §7.3.10, .13, .14; the
    // peripherals' boundary addresses, §2.3 Table 1.
    for (enr, b, base, name) in [
        (RCC_AHB1ENR, 0, GPIOA_MODER, "GPIOA"),
        (RCC_AHB1ENR, 22, DMA2_LIFCR - 8, "DMA2"),
        (RCC_APB2ENR, 8, ADC1, "ADC1"),
        (RCC_APB2ENR, 9, ADC2, "ADC2"),
        (RCC_APB1ENR, 29, DAC_CR, "DAC"),
        (RCC_APB1ENR, 0, TIM2, "TIM2"),
        (RCC_APB1ENR, 1, TIM3, "TIM3"),
        (RCC_APB1ENR, 3, TIM5, "TIM5"),
        (RCC_APB1ENR, 17, USART2_BRR - 8, "USART2"),
    ] {
        let on = boot.iter().position(|e| {
            matches!(e, Ev::B(a, n, true) if *a == enr && *n == b)
                || matches!(e, Ev::W(a, v) if *a == enr && bit(*v, b))
        });
        let used = first(
            boot,
            name,
            |e| matches!(e, Ev::W(a, _) if (base..base + 0x100).contains(a)),
        );
        assert!(
            on.is_some_and(|i| i < used),
            "{name}: clock enable {on:?}, first write {used}"
        );
    }
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn both_adcs_run_on_a_21_mhz_clock_and_convert_within_their_periods() {
    let t = trace();
    // ADC_CCR.ADCPRE (17:16): 00 /2, 01 /4, 10 /6, 11 /8 of PCLK2 = 84 MHz; ADC1 and ADC2
    // share it. Every write, the calibration's too: no conversion ever runs above 36 MHz.
    let ccr = writes(t.boot(), ADC_CCR);
    assert!(!ccr.is_empty());
    for v in &ccr {
        let adcclk = 84e6 / f64::from(2 * (field(*v, 17, 16) + 1));
        assert!(
            adcclk <= ADCCLK_MAX,
            "ADC_CCR 0x{v:08x}: ADCCLK {adcclk} Hz"
        );
    }
    assert_eq!(field(*ccr.last().unwrap(), 17, 16), 0b01, "ADCCLK = 21 MHz");
    // Channel 1 (PA1) at 15 cycles (SMP1 = 001, §13.13.5) and 12 bits: (15 + 12) / 21 MHz
    // = 1.29 µs, inside the capture's 10 µs.
    for adc in [ADC1, ADC2] {
        let smpr2 = last(t, adc + ADC_SMPR2);
        let cycles =
            [3.0, 15.0, 28.0, 56.0, 84.0, 112.0, 144.0, 480.0][field(smpr2, 5, 3) as usize];
        let conv_s = (cycles + 12.0) / 21e6;
        assert_eq!(cycles, 15.0, "ADC 0x{adc:08x} SMPR2 0x{smpr2:08x}");
        assert!(conv_s < 10e-6, "{conv_s} s");
        assert_eq!(
            field(last(t, adc + ADC_SQR3), 4, 0),
            1,
            "first conversion: channel 1"
        );
    }
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn adc1_converts_on_tim2_at_10_khz_and_adc2_on_tim3_at_100_khz() {
    let t = trace();
    // ADC_CR2 (§13.13.3): ADON 0, DMA 8, DDS 9, EOCS 10, EXTSEL 27:24 (0110 TIM2 TRGO, 1000
    // TIM3 TRGO), EXTEN 29:28 (01 rising edge). ADC_CR1: EOCIE 5.
    let cr2 = last(t, ADC1 + ADC_CR2);
    assert_eq!(field(cr2, 27, 24), 0b0110, "ADC1 EXTSEL: 0x{cr2:08x}");
    assert_eq!(field(cr2, 29, 28), 0b01, "ADC1 EXTEN: 0x{cr2:08x}");
    assert!(bit(cr2, 10) && bit(cr2, 0), "ADC1 EOCS, ADON: 0x{cr2:08x}");
    assert!(bit(last(t, ADC1 + ADC_CR1), 5), "ADC1 EOCIE");
    let cr2 = last(t, ADC2 + ADC_CR2);
    assert_eq!(field(cr2, 27, 24), 0b1000, "ADC2 EXTSEL: 0x{cr2:08x}");
    assert_eq!(field(cr2, 29, 28), 0b01, "ADC2 EXTEN: 0x{cr2:08x}");
    assert!(
        bit(cr2, 8) && bit(cr2, 9) && bit(cr2, 0),
        "ADC2 DMA, DDS, ADON: 0x{cr2:08x}"
    );

    // The timers count 2 × PCLK1 = 84 MHz (§7.2); update = trigger output (MMS 6:4 = 010,
    // §18.4.2); f = 84 MHz / ((PSC + 1)(ARR + 1)) as set when the counter starts (CEN), a
    // PSC never written being its reset value 0.
    for (tim, rate_hz) in [(TIM2, 10_000.0), (TIM3, 100_000.0)] {
        let cen = first(
            &t.events,
            "the counter's start",
            |e| matches!(e, Ev::W(a, v) if *a == tim + TIM_CR1 && bit(*v, 0)),
        );
        let before = &t.events[..cen];
        let psc = writes(before, tim + TIM_PSC).last().copied().unwrap_or(0);
        let arr = *writes(before, tim + TIM_ARR).last().expect("ARR written");
        let f = 84e6 / f64::from(psc + 1) / f64::from(arr + 1);
        assert_eq!(f, rate_hz, "0x{tim:08x}: PSC {psc} ARR {arr}");
        let cr2 = *writes(before, tim + TIM_CR2).last().expect("CR2 written");
        assert_eq!(field(cr2, 6, 4), 0b010, "0x{tim:08x} MMS");
    }
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn tim5_counts_microseconds_over_the_full_32_bits() {
    let t = trace();
    // 84 MHz / (PSC + 1) = 1 MHz; the prescaler is loaded by an update event (UG, §18.4.6)
    // before counting; ARR = 2³² − 1 so that the count wraps every 2³² µs, what the 64-bit
    // extension adds per wrap (an ARR of 0xFFFF_FFFE gains 1 µs every 71.6 min).
    let boot = t.boot();
    let psc = last(t, TIM5 + TIM_PSC);
    assert_eq!(84e6 / f64::from(psc + 1), 1e6, "TIM5 PSC {psc}");
    let arr = last(t, TIM5 + TIM_ARR);
    assert_eq!(arr, u32::MAX, "TIM5 ARR 0x{arr:08x}");
    let psc_at = first(
        boot,
        "TIM5 PSC",
        |e| matches!(e, Ev::W(a, _) if *a == TIM5 + TIM_PSC),
    );
    let ug_at = first(
        boot,
        "TIM5 UG",
        |e| matches!(e, Ev::W(a, v) if *a == TIM5 + TIM_EGR && bit(*v, 0)),
    );
    let cen_at = first(
        boot,
        "TIM5 CEN",
        |e| matches!(e, Ev::W(a, v) if *a == TIM5 + TIM_CR1 && bit(*v, 0)),
    );
    assert!(psc_at < ug_at && ug_at < cen_at);
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_capture_stream_is_dma2_stream_2_channel_1_double_buffered_from_adc2() {
    let t = trace();
    // DMA2 stream 2 channel 1 is ADC2 (§10.3.3, Table 43). DMA_SxCR (§10.5.5): EN 0, DMEIE 1,
    // TEIE 2, TCIE 4, DIR 7:6 (00 peripheral to memory), CIRC 8, PINC 9, MINC 10, PSIZE 12:11,
    // MSIZE 14:13 (01 half-word), PL 17:16, DBM 18, CT 19, CHSEL 27:25.
    let cr = last(t, DMA2_S2CR);
    assert_eq!(field(cr, 27, 25), 1, "CHSEL: 0x{cr:08x}");
    assert_eq!(field(cr, 7, 6), 0b00, "DIR: 0x{cr:08x}");
    // DBM; circular mode comes with it (§10.3.9: CIRC forced by hardware in double-buffer
    // mode).
    assert!(bit(cr, 18), "DBM: 0x{cr:08x}");
    assert!(!bit(cr, 19), "CT: M0 first: 0x{cr:08x}");
    assert_eq!(
        (field(cr, 12, 11), field(cr, 14, 13)),
        (0b01, 0b01),
        "sizes: 0x{cr:08x}"
    );
    assert!(bit(cr, 10) && !bit(cr, 9), "MINC, no PINC: 0x{cr:08x}");
    // The capture's requests before any other stream's (DMA2's arbiter, §10.3.4).
    assert_eq!(field(cr, 17, 16), 0b11, "PL very high: 0x{cr:08x}");
    // An interrupt at each full buffer and at a transfer error (the stream then stops, and
    // only its interrupt can re-arm it).
    assert!(bit(cr, 4) && bit(cr, 2), "TCIE, TEIE: 0x{cr:08x}");
    assert!(!bit(cr, 0), "enabled at start-up: 0x{cr:08x}");
    assert_eq!(
        last(t, DMA2_S2PAR),
        ADC2 + ADC_DR,
        "peripheral address: ADC2_DR"
    );
    assert_eq!(last(t, DMA2_S2NDTR), 64);
    let (m0, m1) = (last(t, DMA2_S2M0AR), last(t, DMA2_S2M1AR));
    assert_eq!(m1.wrapping_sub(m0), 64 * 2, "M0 0x{m0:08x}, M1 0x{m1:08x}");
    assert!(
        (0x2000_0000..0x2002_0000 - 256).contains(&m0),
        "buffers in SRAM: 0x{m0:08x}"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_dac_drives_pa4_with_its_output_buffer_at_mid_scale() {
    let t = trace();
    // DAC_CR (§14.5.1): EN1 0, BOFF1 1 (0: buffer on, for the amplifier's input impedance).
    let cr = last(t, DAC_CR);
    assert!(bit(cr, 0) && !bit(cr, 1), "DAC_CR 0x{cr:08x}");
    assert_eq!(last(t, DAC_DHR12R1), 2048, "zero drive is mid-scale");
    // PA4 and PA1 analog (MODER 11, §8.4.1).
    let moder = last(t, GPIOA_MODER);
    assert_eq!(field(moder, 9, 8), 0b11, "PA4: 0x{moder:08x}");
    assert_eq!(field(moder, 3, 2), 0b11, "PA1: 0x{moder:08x}");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_console_is_usart2_at_115200_baud_on_pa2_and_pa3_af7() {
    let t = trace();
    // USART2 on APB1 (42 MHz); OVER8 (CR1 bit 15) = 0: baud = f_CK / (16 × USARTDIV), BRR =
    // USARTDIV × 16 (mantissa 15:4, fraction 3:0, §30.3.4).
    let cr1 = last(t, USART2_CR1);
    assert!(!bit(cr1, 15), "OVER8: 0x{cr1:08x}");
    assert!(
        bit(cr1, 13) && bit(cr1, 3) && bit(cr1, 2),
        "UE TE RE: 0x{cr1:08x}"
    );
    assert!(bit(cr1, 5), "RXNEIE: 0x{cr1:08x}");
    let brr = last(t, USART2_BRR);
    let usartdiv = f64::from(field(brr, 15, 4)) + f64::from(field(brr, 3, 0)) / 16.0;
    let baud = 42e6 / (16.0 * usartdiv);
    assert!(
        (baud / 115_200.0 - 1.0).abs() < 0.01,
        "{baud} Bd from BRR 0x{brr:04x}"
    );
    // PA2 (TX), PA3 (RX): alternate function (MODER 10) 7 (AFRL 11:8, 15:12; datasheet
    // Table 9: USART2 is AF7).
    let moder = last(t, GPIOA_MODER);
    assert_eq!((field(moder, 5, 4), field(moder, 7, 6)), (0b10, 0b10));
    let afrl = last(t, GPIOA_AFRL);
    assert_eq!(
        (field(afrl, 11, 8), field(afrl, 15, 12)),
        (7, 7),
        "AFRL 0x{afrl:08x}"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_watchdog_resets_after_2_s_and_stops_while_a_debugger_halts_the_core() {
    let t = trace();
    // IWDG (§21.4): KR 0x5555 unlocks PR and RLR; PR 6 = /256; timeout = (RLR + 1) × 256 /
    // 32 kHz (LSI, nominal; §21.3, Table 107); KR 0xCCCC starts it.
    let boot = t.boot();
    let kr = writes(boot, IWDG_KR);
    let pr = last(t, IWDG_PR);
    let rlr = last(t, IWDG_RLR);
    assert_eq!(pr, 6, "IWDG_PR");
    let timeout_s = f64::from(rlr + 1) * 256.0 / 32_000.0;
    assert!((timeout_s - 2.0).abs() < 0.01, "{timeout_s} s (RLR {rlr})");
    let unlock = first(
        boot,
        "IWDG unlock",
        |e| matches!(e, Ev::W(a, 0x5555) if *a == IWDG_KR),
    );
    let pr_at = first(
        boot,
        "IWDG_PR",
        |e| matches!(e, Ev::W(a, _) if *a == IWDG_PR),
    );
    assert!(unlock < pr_at && kr.contains(&0xCCCC), "KR writes {kr:x?}");
    // DBGMCU_APB1_FZ.DBG_IWDG_STOP (bit 12, §38.16.4): a breakpoint does not reset the board.
    assert!(bit(last(t, DBGMCU_APB1_FZ), 12), "DBG_IWDG_STOP");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_sampling_interrupt_preempts_the_console_and_the_capture_which_preempt_the_service() {
    let t = trace();
    // NVIC_IPRx: one byte per interrupt, the upper 4 bits implemented (PM0214 §4.3.7); a lower
    // value is a higher priority. ISERx: the enabled interrupts.
    let boot = t.boot();
    let mut prio = BTreeMap::new();
    let mut enabled = 0u64;
    for e in boot {
        if let Ev::W(a, v) = e {
            if (NVIC_IPR..NVIC_IPR + 240).contains(a) {
                // Byte writes at NVIC_IPR + n (a word write would set four at once).
                prio.insert(a - NVIC_IPR, *v & 0xFF);
            } else if *a == NVIC_ISER || *a == NVIC_ISER + 4 {
                enabled |= u64::from(*v) << (8 * (a - NVIC_ISER));
            }
        }
    }
    for irq in [IRQ_ADC, IRQ_USART2, IRQ_DMA2_STREAM2, IRQ_EXTI1] {
        assert!(enabled >> irq & 1 == 1, "IRQ {irq} not enabled");
    }
    let p = |irq: u32| prio[&irq];
    assert!(p(IRQ_ADC) < p(IRQ_USART2), "{prio:?}");
    assert!(p(IRQ_ADC) < p(IRQ_DMA2_STREAM2), "{prio:?}");
    // The capture's block lasts 640 µs; the console service (the EXTI1 dispatcher) formats
    // lines for longer: the capture must preempt it.
    assert!(p(IRQ_DMA2_STREAM2) < p(IRQ_EXTI1), "{prio:?}");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn sampling_starts_once_interrupts_are_on_with_adc1_cleared_first() {
    let t = trace();
    let ev = &t.events;
    let on = t.marker("interrupts-on", "");
    // TIM2 starts counting (CR1.CEN): its first update triggers ADC1. It must come after the
    // interrupts are on, or a conversion ends (and the next overruns, with EOCS = 1) before
    // the sampling task can run.
    let cen = first(
        ev,
        "TIM2 CEN",
        |e| matches!(e, Ev::W(a, v) if *a == TIM2 + TIM_CR1 && bit(*v, 0)),
    );
    assert!(
        on < cen,
        "TIM2 started at event {cen}, interrupts on at {on}"
    );
    // No update event on TIM2 while ADC1 listens to it (UG with MMS = update is a trigger).
    assert!(
        !ev.iter()
            .any(|e| matches!(e, Ev::W(a, v) if *a == TIM2 + TIM_EGR && bit(*v, 0))),
        "TIM2 UG"
    );
    // ADC1's flags cleared (OVR, bit 5, written 0) and its data register read after its last
    // configuration and before TIM2 starts: the calibration's result is not a sample.
    let configured = ev[..cen]
        .iter()
        .rposition(|e| matches!(e, Ev::W(a, _) if *a == ADC1 + ADC_CR2 || *a == ADC1 + ADC_CR1))
        .expect("ADC1 configured");
    let cleared = ev[configured..cen]
        .iter()
        .position(|e| matches!(e, Ev::W(a, v) if *a == ADC1 + ADC_SR && !bit(*v, 5)));
    let read = ev[configured..cen]
        .iter()
        .position(|e| matches!(e, Ev::R(a, _) if *a == ADC1 + ADC_DR));
    assert!(
        cleared.is_some() && read.is_some(),
        "ADC1 SR cleared {cleared:?}, DR read {read:?}"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_sampling_task_runs_on_an_end_of_conversion_and_writes_the_dac() {
    let t = trace();
    let ph = t.phase("sample");
    assert_eq!(
        irqs(ph),
        [IRQ_ADC, IRQ_ADC],
        "one sampling task per end of conversion"
    );
    let reads = ph
        .iter()
        .filter(|e| matches!(e, Ev::R(a, _) if *a == ADC1 + ADC_DR))
        .count();
    assert_eq!(reads, 2);
    // The drive is off: mid-scale.
    assert_eq!(writes(ph, DAC_DHR12R1), [2048, 2048]);
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn an_adc1_overrun_clears_ovr_alone_and_reads_the_data_register() {
    let t = trace();
    // ADC_SR's flags are rc_w0 (§13.13.1): a written 0 clears, a 1 leaves. Clearing OVR
    // (bit 5) must write 1 to AWD, EOC, JEOC, JSTRT, STRT (bits 4:0) so that no flag set in
    // between is lost; the data register is read so that EOC does not stay set (§13.8.1).
    let ph = t.phase("adc-overrun");
    let sr = writes(ph, ADC1 + ADC_SR);
    assert!(!sr.is_empty(), "OVR never cleared");
    for v in &sr {
        assert_eq!(
            v & 0x3F,
            0x1F,
            "ADC1_SR written 0x{v:x}: clears more than OVR"
        );
    }
    let sr_at = first(
        ph,
        "ADC1_SR write",
        |e| matches!(e, Ev::W(a, _) if *a == ADC1 + ADC_SR),
    );
    assert!(
        ph[sr_at..]
            .iter()
            .any(|e| matches!(e, Ev::R(a, _) if *a == ADC1 + ADC_DR)),
        "ADC1_DR not read after the overrun"
    );
    assert_eq!(
        irqs(ph),
        [IRQ_ADC],
        "the overrun left EOC set: the interrupt came again"
    );
}

/// The writes of a stream re-arm in `evs`, checked in order (RM0090 §10.3.17, §13.8.1): the
/// stream disabled, its flags cleared, M0 first with 64 transfers, ADC2's overrun cleared,
/// the stream enabled; returns the index of the enable.
fn rearm_in(evs: &[Ev], what: &str) -> usize {
    let disabled = first(
        evs,
        &format!("{what}: stream disabled"),
        |e| matches!(e, Ev::W(a, v) if *a == DMA2_S2CR && !bit(*v, 0)),
    );
    let rest = &evs[disabled..];
    let flags = first(rest, &format!("{what}: stream 2 flags cleared"), |e| {
        // LIFCR (§10.5.3): CTEIF2 19, CTCIF2 21 among 21:16.
        matches!(e, Ev::W(a, v) if *a == DMA2_LIFCR && bit(*v, 19) && bit(*v, 21))
    });
    let ndtr = first(
        rest,
        &format!("{what}: NDTR"),
        |e| matches!(e, Ev::W(a, 64) if *a == DMA2_S2NDTR),
    );
    let ovr = first(
        rest,
        &format!("{what}: ADC2 OVR cleared"),
        |e| matches!(e, Ev::W(a, v) if *a == ADC2 + ADC_SR && !bit(*v, 5) && v & 0x1F == 0x1F),
    );
    let enabled = first(
        rest,
        &format!("{what}: stream enabled"),
        |e| matches!(e, Ev::W(a, v) if *a == DMA2_S2CR && bit(*v, 0) && !bit(*v, 19)),
    );
    assert!(
        flags < enabled && ndtr < enabled && ovr < enabled,
        "{what}: flags {flags}, NDTR {ndtr}, OVR {ovr}, enable {enabled}"
    );
    disabled + enabled
}

/// Writes to TIM3's registers in `evs`.
fn tim3_writes(evs: &[Ev]) -> Vec<(u32, u32)> {
    evs.iter()
        .filter_map(|e| match e {
            Ev::W(a, v) if (TIM3..TIM3 + 0x400).contains(a) => Some((*a - TIM3, *v)),
            _ => None,
        })
        .collect()
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn a_capture_starts_on_a_re_armed_stream() {
    let t = trace();
    // Arming: the stream re-armed, then TIM3 started, so that the first block holds only this
    // capture's samples.
    let ph = t.phase("capture-arm");
    assert!(
        replies(ph)[0].starts_with("capture state=armed"),
        "{:?}",
        replies(ph)
    );
    let enabled = rearm_in(ph, "capture arm");
    let cen = first(
        ph,
        "TIM3 CEN",
        |e| matches!(e, Ev::W(a, v) if *a == TIM3 + TIM_CR1 && bit(*v, 0)),
    );
    assert!(enabled < cen, "TIM3 started before the stream");
    // The next capture, after `capture stop` left a buffer half-filled: re-armed again.
    let ph = t.phase("capture-rearm");
    let r = replies(ph);
    assert!(r[0].starts_with("capture state=done") && r[1].starts_with("capture state=armed"));
    let second = ph
        .iter()
        .rposition(
            |e| matches!(e, Ev::M(k, t) if k == "reply" && t.starts_with("capture state=done")),
        )
        .unwrap();
    rearm_in(&ph[second..], "second capture");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn a_console_line_during_a_capture_leaves_its_timer_and_stream_alone() {
    let t = trace();
    // `status` while the capture records: TIM3 untouched (a restart zeroes its counter and
    // forces an update: the capture's sample phase jumps), the stream too.
    let ph = t.phase("console-armed");
    assert!(replies(ph)[0].starts_with("state="), "{:?}", replies(ph));
    assert_eq!(
        tim3_writes(ph),
        [],
        "TIM3 written while the capture records"
    );
    assert_eq!(
        writes(ph, DMA2_S2CR),
        Vec::<u32>::new(),
        "the stream written while the capture records"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn a_full_capture_block_reaches_the_store() {
    let t = trace();
    // TCIF2 with CT switched to M1: the capture task copies M0 into the segment store.
    let ph = t.phase("capture-block");
    assert!(irqs(ph).contains(&IRQ_DMA2_STREAM2));
    let r = replies(ph);
    assert!(r[0].contains(" samples=64 "), "{r:?}");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn a_stopped_capture_clears_its_streams_flags() {
    let t = trace();
    // After `capture stop`, the next block's interrupt stops TIM3; a block that completed as
    // it stopped raises the interrupt once more, which must clear TCIF2 (DMA_LIFCR bit 21,
    // §10.5.3): a flag left set raises it again at once, for ever (the trace gives up after
    // 2,000 deliveries).
    let ph = t.phase("capture-stopped");
    assert!(
        replies(ph)[0].starts_with("capture state=done"),
        "{:?}",
        replies(ph)
    );
    let dma = irqs(ph)
        .into_iter()
        .filter(|&n| n == IRQ_DMA2_STREAM2)
        .count();
    assert_eq!(dma, 2, "the capture's interrupts: once per block");
    let stopped = first(
        ph,
        "TIM3 stopped",
        |e| matches!(e, Ev::W(a, v) if *a == TIM3 + TIM_CR1 && !bit(*v, 0)),
    );
    let second = ph
        .iter()
        .rposition(|e| matches!(e, Ev::M(k, _) if k == "irq"))
        .unwrap();
    assert!(stopped < second);
    assert!(
        writes(&ph[second..], DMA2_LIFCR)
            .iter()
            .any(|v| bit(*v, 21)),
        "TCIF2 not cleared"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn a_capture_dma_transfer_error_re_arms_the_stream_and_counts_the_lost_samples() {
    let t = trace();
    // The stream stopped (TEIF2, EN = 0, §10.3.18) 1.65 ms after the capture started, with one
    // block (64 samples) delivered; ADC2 overran. Its interrupt re-arms it, and the capture's
    // index goes on with time: 1.65 ms at 100 kHz = 165 samples.
    let ph = t.phase("capture-error");
    assert!(
        irqs(ph).contains(&IRQ_DMA2_STREAM2),
        "no interrupt for a transfer error (TEIE)"
    );
    rearm_in(ph, "transfer error");
    let r = replies(ph);
    let samples: i64 = r[0]
        .split_whitespace()
        .find_map(|w| w.strip_prefix("samples="))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{r:?}"));
    assert!((163..=167).contains(&samples), "{r:?}");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_flash_is_unlocked_with_key1_then_key2_before_it_is_programmed_or_erased() {
    let t = trace();
    let w = flash();
    // §3.6.1: FLASH_CR is locked after reset; KEY1 then KEY2 in FLASH_KEYR unlock it; a wrong
    // key, or a key while unlocked, is a bus error and locks it until the next reset.
    assert_eq!(
        store_sectors(),
        [1, 2],
        "the store is sectors 1 and 2 (Table 5)"
    );
    let broken: Vec<_> = [w.broken("unlock:"), w.broken("keys:")].concat();
    assert!(broken.is_empty(), "{broken:#?}");
    let save = t.phase_range("save");
    assert!(
        w.unlocks.iter().any(|i| save.contains(i)),
        "no unlock during `save`"
    );
    // Every operation in its power-up comes after an unlock (the walk would have flagged a
    // write to a locked FLASH_CR); the first one after KEY1 then KEY2 in that order.
    let first = w.ops_in(&save)[0].at;
    let keys: Vec<u32> = t.events[save.start..first]
        .iter()
        .filter_map(|e| match e {
            Ev::W(a, v) if *a == FLASH_KEYR => Some(*v),
            _ => None,
        })
        .collect();
    assert_eq!(
        keys,
        [KEY1, KEY2],
        "the keys before the save's first operation"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn every_program_and_erase_runs_at_x32_parallelism() {
    let w = flash();
    // §3.6.2, Table 16: at 2.7–3.6 V the parallelism is x32 (PSIZE = 10) for programming and
    // erasing; every FLASH_CR write that sets PG or SER, and every word programmed, has it.
    assert!(w.broken("psize:").is_empty(), "{:#?}", w.broken("psize:"));
    assert!(!w.ops.is_empty(), "no flash operation in the trace");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn erases_select_only_the_store_sectors_then_start_with_strt() {
    let t = trace();
    let w = flash();
    // §3.6.3: SER and SNB set, then STRT; SNB a store sector (never the image's sector 0 or
    // the sectors after the store), never a mass erase.
    let broken: Vec<_> = [w.broken("sector:"), w.broken("strt:")].concat();
    assert!(broken.is_empty(), "{broken:#?}");
    // The save after the cut moves the store: both sectors erased.
    let cut = t.phase_range("cut-save");
    let erased: Vec<u32> = w
        .ops_in(&cut)
        .iter()
        .filter_map(|o| match o.kind {
            FlashOpKind::Erase { snb } => Some(snb),
            FlashOpKind::Program { .. } => None,
        })
        .collect();
    assert_eq!(
        erased,
        store_sectors(),
        "sectors erased by the save after the cut"
    );
    // Each STRT started an erase in the model (a STRT the flash refused would not have).
    let started = t.events[cut]
        .iter()
        .filter(|e| matches!(e, Ev::M(k, _) if k == "flash-erase"))
        .count();
    assert_eq!(started, erased.len());
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn programming_writes_whole_words_inside_the_store_with_pg_set() {
    let t = trace();
    let w = flash();
    // §3.6.4: PG set (and not SER), then one 32-bit write per word at x32, word-aligned,
    // inside the store's sectors.
    assert!(
        w.broken("program:").is_empty(),
        "{:#?}",
        w.broken("program:")
    );
    let words: Vec<u32> = w
        .ops_in(&t.phase_range("save"))
        .iter()
        .filter_map(|o| match o.kind {
            FlashOpKind::Program { addr } => Some(addr),
            FlashOpKind::Erase { .. } => None,
        })
        .collect();
    assert!(words.len() > 4, "the save programmed {} words", words.len());
    // An item's words one after another (the store's index walks: no word written twice).
    let mut sorted = words.clone();
    sorted.dedup();
    assert_eq!(
        sorted, words,
        "a word programmed twice in a row: {words:x?}"
    );
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn each_flash_operation_waits_for_bsy_to_clear() {
    let w = flash();
    // §3.6.3–3.6.4: nothing touches the flash interface (a key, FLASH_CR, another word) until
    // FLASH_SR.BSY reads 0 after an operation.
    assert!(w.broken("bsy:").is_empty(), "{:#?}", w.broken("bsy:"));
    let unwaited: Vec<_> = w.ops.iter().filter(|o| !o.waited).collect();
    assert!(unwaited.is_empty(), "{unwaited:#?}");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_flash_is_locked_after_every_save_and_its_error_flags_cleared_with_ones() {
    let t = trace();
    let w = flash();
    // FLASH_CR.LOCK (bit 31) set again once the operations end: at every console reply the
    // flash is locked.
    assert!(w.broken("relock:").is_empty(), "{:#?}", w.broken("relock:"));
    let save = t.phase_range("save");
    let last_op = w.ops_in(&save).last().expect("the save's operations").at;
    assert!(
        w.locks.iter().any(|&i| i > last_op && save.contains(&i)),
        "no LOCK after the save's last operation"
    );
    // The error flags are rc_w1 (§3.9.4): cleared by writing 1s, before FLASH_CR is written
    // again, and none left at a reply.
    assert!(w.broken("errors:").is_empty(), "{:#?}", w.broken("errors:"));
    // The board whose option bytes protect the store: WRPERR (bit 4) read and cleared, the
    // flash locked, the save refused.
    let wrp = t.phase_range("wrp-save");
    let read = w
        .error_reads
        .iter()
        .find(|(i, e)| wrp.contains(i) && bit(*e, SR_WRPERR))
        .unwrap_or_else(|| panic!("no WRPERR read: {:?}", w.error_reads));
    assert!(
        w.error_clears
            .iter()
            .any(|(i, e)| *i > read.0 && wrp.contains(i) && bit(*e, SR_WRPERR)),
        "WRPERR not cleared: {:?}",
        w.error_clears
    );
    assert!(w.locks.iter().any(|&i| i > read.0 && wrp.contains(&i)));
    let ph = t.phase("wrp-save");
    reply_starting(ph, "error: save failed");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_sampling_deadlines_are_paused_while_the_flash_stalls_the_cpu() {
    let t = trace();
    let w = flash();
    // The CPU stalls on the flash during each operation (§3.6.3–3.6.4: one bank), so samples
    // come late, or overrun during a 16 KiB erase; the controller counts them instead of
    // faulting while the save runs.
    for phase in ["save", "cut-save"] {
        let r = t.phase_range(phase);
        let ops = w.ops_in(&r);
        let (start, end) = (ops[0].at, ops.last().unwrap().at);
        let sampled = t.events[start..end]
            .iter()
            .filter(|e| matches!(e, Ev::M(k, txt) if k == "irq" && txt.starts_with(&format!("{IRQ_ADC} "))))
            .count();
        assert!(
            sampled > 0,
            "{phase}: no sampling task during the flash writes"
        );
        let status = reply_starting(&t.events[r], "state=");
        assert_eq!(value_of(status, "fault"), "none", "{phase}: {status}");
    }
    // A 500 ms erase: ADC1 overran (OVR, bit 5 of ADC_SR, read by the sampling task), still
    // no fault.
    let cut = t.phase_range("cut-save");
    let erase = w
        .ops_in(&cut)
        .into_iter()
        .find(|o| matches!(o.kind, FlashOpKind::Erase { .. }))
        .unwrap()
        .at;
    assert!(
        t.events[erase..cut.end]
            .iter()
            .any(|e| matches!(e, Ev::R(a, v) if *a == ADC1 + ADC_SR && bit(*v, 5))),
        "no overrun seen during the erase"
    );
    // After the save the checks are back: the same overrun is a fault.
    let status = reply_starting(t.phase("cut-overrun"), "state=");
    assert_eq!(value_of(status, "fault"), "adc-overrun", "{status}");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn the_next_power_up_loads_what_was_saved() {
    let t = trace();
    // `rig beam-150`, `gap 1.5`, `save`: the store holds the beam model at 1.5 mm.
    let save = t.phase("save");
    let stored = reply_starting(save, "store ");
    assert_eq!(value_of(stored, "state"), "ok", "{stored}");
    let hash = value_of(stored, "rig_hash");
    // `revert` reads it back from the flash.
    let reverted = reply_starting(t.phase("revert"), "model ");
    assert_eq!(value_of(reverted, "rig"), "stored", "{reverted}");
    assert_eq!(value_of(reverted, "rig_hash"), hash, "{reverted}");
    // The next power-up, the same flash: `init` starts from the stored settings.
    let reboot = t.phase("reboot");
    let id = reply_starting(reboot, "id ");
    assert_eq!(
        (
            value_of(id, "rig"),
            value_of(id, "rig_hash"),
            value_of(id, "store"),
            value_of(id, "gap_mm")
        ),
        ("stored", hash, "ok", "1.50"),
        "{id}"
    );
    let store = reply_starting(reboot, "store ");
    assert_eq!(value_of(store, "saves"), "1", "{store}");
}

#[test]
#[ignore = "needs python3 with unicorn and pyelftools, and the rig image (cargo fw-build)"]
fn reset_replies_then_requests_a_system_reset_and_the_board_restarts_on_the_store() {
    let t = trace();
    // SCB_AIRCR (PM0214 §4.4.4): VECTKEY 0x05FA in bits 31:16, SYSRESETREQ bit 2.
    const SCB_AIRCR: u32 = 0xE000_ED0C;
    let r = t.phase_range("reset");
    let ph = &t.events[r.clone()];
    assert_eq!(replies(ph).first(), Some(&"ok"), "{:?}", replies(ph));
    let reply = first(
        ph,
        "the reply",
        |e| matches!(e, Ev::M(k, _) if k == "reply"),
    );
    let aircr = first(
        ph,
        "SYSRESETREQ",
        |e| matches!(e, Ev::W(a, v) if *a == SCB_AIRCR && field(*v, 31, 16) == 0x05FA && bit(*v, 2)),
    );
    assert!(reply < aircr, "the reset before its reply");
    // The flash locked when it resets (the walk checks it at every reply; here at the reset).
    let w = flash();
    let last_unlock = w.unlocks.iter().rfind(|&&i| i < r.start + aircr);
    let last_lock = w.locks.iter().rfind(|&&i| i < r.start + aircr);
    assert!(
        last_unlock <= last_lock,
        "unlocked at the reset: {last_unlock:?} {last_lock:?}"
    );
    // The restart loads the stored settings.
    let stored = reply_starting(t.phase("save"), "store ");
    let id = reply_starting(t.phase("after-reset"), "id ");
    assert_eq!(
        (value_of(id, "rig"), value_of(id, "rig_hash")),
        ("stored", value_of(stored, "rig_hash")),
        "{id}"
    );
}

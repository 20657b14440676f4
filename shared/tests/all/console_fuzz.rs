//! The console path under 1,000,000 generated inputs (valid commands, mutated commands, any
//! bytes, over-long lines, partial commands, injected receive errors), through the link, the
//! service and the controller, checked against an independent count of the lines sent:
//! - nothing panics;
//! - every line gets exactly one reply, in order, and every reply is one text line that fits
//!   the reply size and never looks like an asynchronous line (`!`);
//! - a line hit by a receive error is answered `error: line lost` and changes nothing, and an
//!   over-long line, or one holding a control byte, is answered `error: line too long or not
//!   text` and changes nothing (the line-editing rules written out independently here).
//!
//! Seeded (ChaCha8): the same inputs on every machine. CI also runs it as a release build.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shared::capture::Capture;
use shared::console::link::{MAX_REPLY, TX_CAPACITY};
use shared::console::serve::{ReplyText, format_answer};
use shared::console::{Board, BoardInfo, Direct, Link, MAX_LINE, RxError, Version, answer};
use shared::control::{Controller, ControllerConfig, Prediction};
use shared::model::RigId;
use shared::store::Store;
use shared::store::ram_flash::{PAGE_BYTES, RamFlash};

const INPUTS: usize = 1_000_000;

const WORDS: &[&str] = &[
    "status",
    "rig",
    "gap",
    "start",
    "stop",
    "tune",
    "freq",
    "clear",
    "help",
    "stream",
    "id",
    "diag",
    "capture",
    "link-timeout",
    "model",
    "calib",
    "draft",
    "save",
    "revert",
    "store",
    "#7 status",
    "#123456789 freq",
    "#x",
];
const ARGS: &[&str] = &[
    "",
    "wires",
    "beam-170",
    "0",
    "0.5",
    "-1",
    "3.66",
    "40",
    "1e3",
    "nan",
    "on",
    "off",
    "arm",
    "get",
    "identify",
    "adopt",
    "stop",
    "2",
    "31",
    "99",
    "0.1",
    "1.5",
    "x",
    "mass_kg",
    "law",
    "hunt-crossley",
    "suspension",
    "beam",
    "stiffness",
    "volts_per_n",
    "force_limit_n",
    "begin",
    "apply",
    "discard",
    "0x3fd3126e978d4fe0",
];

/// What the generator sent as one line, for the independent check.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Sent {
    /// A line whose bytes all arrived.
    Clean,
    /// A line with a receive error injected.
    Corrupted,
    /// A line longer than MAX_LINE.
    TooLong,
    /// A line holding a control byte (other than the editing ones).
    Control,
    /// Nothing to answer (nothing kept, no error, no control byte).
    Empty,
}

/// What the rig makes of a line's `bytes` (its end not included) with a receive error flagged
/// before byte `error_at` (or after the last at `bytes.len()`), by the console's line-editing
/// rules written out independently: escape sequences swallowed (`ESC [` … a final byte in
/// 0x40–0x7e, `ESC O x`, `ESC x`); Backspace and Delete remove a UTF-8 character unless a
/// control byte spoiled the line; other control bytes spoil it; the byte that would make it
/// longer than MAX_LINE refuses it at once (a receive error after that is not reported again).
fn received(bytes: &[u8], error_at: Option<usize>) -> Sent {
    let mut kept: Vec<u8> = Vec::new();
    let mut control = false;
    // 0: none, 1: after ESC, 2: in `ESC [`, 3: after `ESC O`.
    let mut escape = 0;
    for (i, &b) in bytes.iter().enumerate() {
        match escape {
            1 => {
                escape = match b {
                    b'[' => 2,
                    b'O' => 3,
                    _ => 0,
                };
                continue;
            }
            2 => {
                if (0x40..=0x7e).contains(&b) {
                    escape = 0;
                }
                continue;
            }
            3 => {
                escape = 0;
                continue;
            }
            _ => {}
        }
        match b {
            0x1b => escape = 1,
            0x08 | 0x7f if !control => {
                while let Some(x) = kept.pop() {
                    if x & 0xc0 != 0x80 {
                        break;
                    }
                }
            }
            0x08 | 0x7f => {}
            0x00..=0x08 | 0x0a..=0x1f => control = true,
            _ if kept.len() == MAX_LINE => {
                return if error_at.is_some_and(|e| e <= i) {
                    Sent::Corrupted
                } else {
                    Sent::TooLong
                };
            }
            _ => kept.push(b),
        }
    }
    if error_at.is_some() {
        Sent::Corrupted
    } else if control {
        Sent::Control
    } else if kept.is_empty() {
        Sent::Empty
    } else {
        Sent::Clean
    }
}

fn command_line(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut s = String::from(WORDS[rng.random_range(0..WORDS.len())]);
    for _ in 0..rng.random_range(0..4) {
        s.push(' ');
        s.push_str(ARGS[rng.random_range(0..ARGS.len())]);
    }
    if rng.random_bool(0.2) {
        s = s.to_uppercase();
    }
    s.into_bytes()
}

fn mutate(rng: &mut ChaCha8Rng, mut line: Vec<u8>) -> Vec<u8> {
    for _ in 0..rng.random_range(1..4) {
        let at = rng.random_range(0..=line.len());
        match rng.random_range(0..3) {
            0 if at < line.len() => {
                line.remove(at);
            }
            1 if at < line.len() => line[at] = rng.random(),
            _ => line.insert(at, rng.random()),
        }
    }
    line
}

/// Bytes of one input, never containing a line terminator (the caller ends the line).
fn body(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut b = match rng.random_range(0..100) {
        0..30 => command_line(rng),
        30..55 => {
            let l = command_line(rng);
            mutate(rng, l)
        }
        55..75 => (0..rng.random_range(0..100))
            .map(|_| rng.random())
            .collect(),
        75..90 => (0..rng.random_range(MAX_LINE + 1..200))
            .map(|_| rng.random_range(b' '..=b'~'))
            .collect(),
        _ => {
            // A partial command: a prefix of one, the rest of the line something else.
            let l = command_line(rng);
            let cut = rng.random_range(0..=l.len());
            let mut p = l[..cut].to_vec();
            p.extend(command_line(rng));
            p
        }
    };
    b.retain(|&c| c != b'\n' && c != b'\r');
    b
}

fn board() -> BoardInfo {
    BoardInfo {
        firmware: Version::of("0.0.0"),
        board: Board::Virtual,
        uptime_ms: 0,
        stack_hwm_bytes: 0,
        stack_size_bytes: 0,
        sample_gap_max_us: 0,
    }
}

#[test]
fn a_million_console_inputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_c0de);
    let mut link = Link::new();
    let mut controller = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
    let mut capture = Capture::new();
    let mut commission = shared::commission::Commission::new();
    let mut mem = vec![0xffu8; 2 * PAGE_BYTES];
    let mut store = Store::new(RamFlash::new(&mut mem), 0..(2 * PAGE_BYTES) as u32).unwrap();
    let mut reply = ReplyText::new();
    let mut sent: Vec<Sent> = Vec::new();
    let mut tx: Vec<u8> = Vec::new();
    let (mut replies, mut lost, mut too_long, mut control) = (0usize, 0usize, 0usize, 0usize);
    for input in 0..INPUTS {
        // Now and then a model result arrives, so that `start` can run.
        if input % 1000 == 0
            && let Some(req) = controller.take_model_request()
        {
            let p = Prediction {
                model_hash: req.model_hash,
                gap_mm: req.gap_mm,
                target_hz: 3.6,
                band_hz: [2.2, 4.7],
                impact_force_mg: 32.0,
                impact_force_n: 93.5,
                amplitude_mm: 0.89,
                weight_n: 2.92,
                natural_freq_hz: 1.82,
            };
            controller.set_prediction(req.generation, Ok(p));
        }
        let bytes = body(&mut rng);
        let error_at = rng
            .random_bool(0.05)
            .then(|| rng.random_range(0..=bytes.len()));
        for (i, &b) in bytes.iter().enumerate() {
            if error_at == Some(i) {
                link.on_rx_error(RxError::Overrun);
            }
            link.on_rx_byte(b);
        }
        if error_at == Some(bytes.len()) {
            link.on_rx_error(RxError::Framing);
        }
        let kind = received(&bytes, error_at);
        // An empty clean line gets no reply (blank lines are skipped).
        if kind != Sent::Empty {
            sent.push(kind);
        }
        link.on_rx_byte(if rng.random_bool(0.5) { b'\n' } else { b'\r' });

        // The service answers every line it can; the UART drains at random speed.
        while let Some(line) = link.next_line() {
            let before = controller.status();
            let a = {
                let mut d = Direct {
                    controller: &mut controller,
                    capture: &mut capture,
                    board: board(),
                    link: &mut link,
                    store: &mut store,
                    commission: &mut commission,
                    reset: false,
                };
                answer(&mut d, line.as_line())
            };
            format_answer(&a, &mut reply);
            assert!(reply.len() <= MAX_REPLY);
            // The echo is a terminal's convenience, checked in the link's tests: keep the
            // transmitted text replies only.
            link.set_echo(false);
            let k = sent.get(replies).copied();
            match k {
                Some(Sent::Corrupted) => {
                    assert_eq!(reply.as_str(), "error: line lost", "input {input}");
                    assert_eq!(controller.status(), before, "input {input}");
                    lost += 1;
                }
                Some(Sent::TooLong) => {
                    assert!(reply.starts_with("error: line too long"), "{reply}");
                    assert_eq!(controller.status(), before);
                    too_long += 1;
                }
                Some(Sent::Control) => {
                    assert_eq!(reply.as_str(), "error: line too long or not text");
                    assert_eq!(controller.status(), before);
                    control += 1;
                }
                Some(Sent::Clean) => {}
                Some(Sent::Empty) | None => {
                    panic!("a reply without a line at input {input}: {reply}")
                }
            }
            link.push_reply(&reply);
            replies += 1;
        }
        for _ in 0..rng.random_range(0..TX_CAPACITY) {
            match link.pop_tx() {
                Some(b) => tx.push(b),
                None => break,
            }
        }
        // Keep the controller alive: a few samples now and then.
        if input % 97 == 0 {
            for k in 0..50u64 {
                controller.on_sample(Ok(300), (input as u64 * 50 + k) * 100);
            }
            while controller.pop_async().is_some() {}
            while controller.pop_event().is_some() {}
        }
        // Check the transmitted text line by line as it comes.
        if tx.len() > 1 << 16 {
            check_lines(&mut tx);
        }
    }
    while let Some(b) = link.pop_tx() {
        tx.push(b);
    }
    check_lines(&mut tx);
    assert_eq!(replies, sent.len(), "one reply per line");
    // The generator's mix reached every kind.
    assert!(
        lost > 10_000 && too_long > 100_000 && control > 10_000,
        "{lost} {too_long} {control}"
    );
}

/// Every complete transmitted line is a reply: text, `\r\n`-terminated, not `!`.
fn check_lines(tx: &mut Vec<u8>) {
    let end = tx
        .windows(2)
        .rposition(|w| w == b"\r\n")
        .map_or(0, |p| p + 2);
    let text = std::str::from_utf8(&tx[..end]).expect("replies are text");
    for line in text.split_terminator("\r\n") {
        assert!(!line.is_empty() && !line.starts_with('!') && !line.contains('\n'));
        assert!(line.len() <= MAX_REPLY);
    }
    tx.drain(..end);
}

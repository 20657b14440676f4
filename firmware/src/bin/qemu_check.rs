//! The `shared` computations on an emulated Cortex-M4F (QEMU `netduinoplus2`, the STM32F407's
//! memory map), for CI: prints the on-target operating frequency (to compare bit for bit with the
//! host's f32 result) and the executed-instruction counts of one sampling-task call, one
//! integrator step and one full target-frequency computation, plus the stack high-water mark.
//! Exits 0 through semihosting when every budget holds, 1 otherwise.
//!
//! Run: `qemu-system-arm -machine netduinoplus2 -nographic -semihosting-config
//! enable=on,target=native -icount shift=0,sleep=off -kernel
//! target/thumbv7em-none-eabihf/release/qemu-check` (what `tests/tests/qemu.rs` does).
//! With `-icount shift=0` SysTick counts executed instructions exactly and repeatably.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
use rig_firmware::stack;

#[cfg(target_os = "none")]
mod target {
    use core::sync::atomic::{AtomicU32, Ordering};

    use cortex_m::peripheral::{SYST, syst::SystClkSource};
    use cortex_m_rt::{entry, exception};
    use cortex_m_semihosting::{debug, hprintln};
    use shared::analysis::{SimSettings, simulator_at};
    use shared::console::Token;
    use shared::control::{
        Command, Controller, ControllerConfig, Prediction, SensorChain, predict,
    };
    use shared::identify::{DropLaw, RecordedDrop, identify_drop};
    use shared::integrate::PhaseTable;
    use shared::model::{ModelEdit, ModelField, RigId};
    // The device crate provides the interrupt vector table.
    use stm32f4xx_hal as _;

    /// The budgets (docs/operator.md): the target computation ≤ 84 M instructions (0.5 s at 168 MHz),
    /// the sampling task ≤ 1,500 instructions per sample.
    const PREDICT_BUDGET: u64 = 84_000_000;
    const SAMPLE_BUDGET: u64 = 1_500;
    /// The drop identification (`capture identify`, run by the console service): ≤ 4.2 M
    /// instructions (25 ms at 168 MHz; a full capture of 32 impacts costs about 4× this
    /// recording's 8); ≤ 42 M (0.25 s) where the Hunt–Crossley fit follows the linear one (the
    /// recorded 22 impacts).
    const IDENTIFY_BUDGET: u64 = 4_200_000;
    const IDENTIFY_HC_BUDGET: u64 = 42_000_000;

    static WRAPS: AtomicU32 = AtomicU32::new(0);

    #[exception]
    fn SysTick() {
        WRAPS.fetch_add(1, Ordering::Relaxed);
    }

    /// Runs `f` and returns its result with the stack it used below this call, bytes (the stack
    /// painted again for it; the high-water mark before it kept in `hwm`).
    /// Also its SysTick ticks (less `overhead`, the cost of reading the clock twice).
    fn own_stack<T>(hwm: &mut u32, overhead: u64, f: impl FnOnce() -> T) -> (T, u64, u32) {
        *hwm = (*hwm).max(crate::stack::high_water_bytes());
        crate::stack::paint();
        let depth = crate::stack::depth_bytes();
        let t0 = now();
        let out = f();
        let ticks = now().saturating_sub(t0 + overhead);
        let used = crate::stack::high_water_bytes();
        *hwm = (*hwm).max(used);
        (out, ticks, used.saturating_sub(depth))
    }

    /// Instructions since start (SysTick counts down from 2²⁴ − 1).
    fn now() -> u64 {
        loop {
            let w = WRAPS.load(Ordering::Relaxed);
            let v = SYST::get_current();
            if WRAPS.load(Ordering::Relaxed) == w {
                return u64::from(w) * 0x0100_0000 + u64::from(0x00FF_FFFF - v);
            }
        }
    }

    #[entry]
    fn main() -> ! {
        crate::stack::paint();
        let mut cp = cortex_m::Peripherals::take().unwrap();
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(0x00FF_FFFF);
        cp.SYST.clear_current();
        cp.SYST.enable_interrupt();
        cp.SYST.enable_counter();
        // Writing VAL does not raise the wrap exception: let the counter reload once, then take
        // the cost of a `now()` pair as the measurement overhead (min of 16).
        while now() < 0x0100_0000 {}
        let overhead = (0..16)
            .map(|_| {
                let a = now();
                now().saturating_sub(a)
            })
            .min()
            .unwrap_or(0);
        hprintln!("insns now_pair_overhead={}", overhead);
        // Calibration: a loop of exactly 2 instructions per iteration (subs + bne).
        let t = now();
        // SAFETY: a register-only countdown loop.
        unsafe {
            core::arch::asm!("1:", "subs {0}, #1", "bne 1b", inout(reg) 1_000_000u32 => _, options(nomem, nostack));
        }
        let calib = now() - t;
        hprintln!("calibration ticks_per_2M_insns={}", calib);
        // SysTick runs at the emulated 168 MHz while `-icount shift=0` executes one instruction
        // per virtual ns: instructions = ticks × 2e6 / calib (≈ ticks / 0.168).
        let insns = |ticks: u64| ticks * 2_000_000 / calib.max(1);

        // 1. The full target-frequency computation (the model task).
        let t0 = now();
        let prediction = predict(&RigId::Wires.preset(), 0.0);
        let predict_insns = now().saturating_sub(t0 + overhead);
        let Ok(p) = prediction else {
            fail("on-target selection failed")
        };
        hprintln!(
            "target_hz={} bits=0x{:08x} band_lo_bits=0x{:08x} band_hi_bits=0x{:08x} force_mg_bits=0x{:08x}",
            p.target_hz,
            p.target_hz.to_bits(),
            p.band_hz[0].to_bits(),
            p.band_hz[1].to_bits(),
            p.impact_force_mg.to_bits()
        );
        let predict_insns = insns(predict_insns);
        hprintln!("insns predict={}", predict_insns);

        // 1b. The same on a model that is no preset, as a rig engineer stores one: the wire
        //     rig's pendulum damped (ζ = 0.01), a 0.31 kg hammer and a spring–dashpot contact
        //     of its own (k_i 5.0163e6 N/m, c_i 1133.7 N s/m): tests/tests/qemu.rs compares
        //     its bits with the host's.
        let Ok(stored) = [
            ModelEdit::Set(ModelField::StiffnessNM, 5_016_300.0),
            ModelEdit::Set(ModelField::DampingNSM, 1_133.7),
            ModelEdit::Set(ModelField::DampingRatio, 0.01),
            ModelEdit::Set(ModelField::MassKg, 0.31),
        ]
        .into_iter()
        .try_fold(RigId::Wires.preset(), |p, e| p.edited(e)) else {
            fail("the stored model's edits were refused")
        };
        let t0 = now();
        let prediction = predict(&stored, 0.0);
        let stored_insns = insns(now().saturating_sub(t0 + overhead));
        let Ok(q) = prediction else {
            fail("on-target selection failed on the stored model")
        };
        hprintln!(
            "stored model_hash=0x{:08x} target_bits=0x{:08x} band_lo_bits=0x{:08x} band_hi_bits=0x{:08x} force_mg_bits=0x{:08x}",
            q.model_hash,
            q.target_hz.to_bits(),
            q.band_hz[0].to_bits(),
            q.band_hz[1].to_bits(),
            q.impact_force_mg.to_bits()
        );
        hprintln!("insns predict_stored={}", stored_insns);

        // 1c. The board's drop identification (`capture identify`) on a recorded capture: the
        //     virtual rig's wire rig with a contact of its own, dropped from 8 mm
        //     (firmware/data/drop-wires-k2.bin, `cargo run -p host-sim --example record_drop`);
        //     tests/tests/qemu.rs compares its bits with the host's.
        static DROP: &[u8] = include_bytes!("../../data/drop-wires-k2.bin");
        let Some(mut rec) = RecordedDrop::parse(DROP, SensorChain::default()) else {
            fail("the recorded drop does not read")
        };
        let mut hwm = 0;
        let (id, ticks, identify_stack) = own_stack(&mut hwm, overhead, || {
            identify_drop(&mut rec, RigId::Wires.preset().mass_kg as f32, 0.0)
        });
        let identify_insns = insns(ticks);
        let Ok(id) = id else {
            fail("the recorded drop was refused")
        };
        let Some(sus) = id.suspension else {
            fail("the recorded drop gave no suspension")
        };
        let DropLaw::SpringDashpot {
            stiffness_n_m,
            damping_n_s_m,
            ..
        } = id.law
        else {
            fail("the recorded drop's law is not the spring–dashpot law")
        };
        hprintln!(
            "identify k_bits=0x{:08x} c_bits=0x{:08x} f_n_bits=0x{:08x} zeta_bits=0x{:08x} fit_bits=0x{:08x}",
            stiffness_n_m.to_bits(),
            damping_n_s_m.to_bits(),
            sus.natural_freq_hz.to_bits(),
            sus.damping_ratio.to_bits(),
            id.fit_ratio.to_bits()
        );
        hprintln!("insns identify={}", identify_insns);
        hprintln!("stack identify_bytes={}", identify_stack);

        // 1d. The same on a Hunt–Crossley contact, where the spring–dashpot law does not fit
        //     and the power law's nonlinear fit runs: the 150 mm beam with Fig. 3.3's contact
        //     (firmware/data/drop-beam150-hc.bin, the same example).
        static DROP_HC: &[u8] = include_bytes!("../../data/drop-beam150-hc.bin");
        let Some(mut rec) = RecordedDrop::parse(DROP_HC, SensorChain::default()) else {
            fail("the recorded Hunt–Crossley drop does not read")
        };
        let (id, ticks, identify_hc_stack) = own_stack(&mut hwm, overhead, || {
            identify_drop(&mut rec, RigId::Beam150.preset().mass_kg as f32, 0.0)
        });
        let identify_hc_insns = insns(ticks);
        let Ok(id) = id else {
            fail("the recorded Hunt–Crossley drop was refused")
        };
        let (
            Some(sus),
            DropLaw::HuntCrossley {
                stiffness,
                exponent,
                lambda_s_m,
                ..
            },
        ) = (id.suspension, id.law)
        else {
            fail("the recorded Hunt–Crossley drop gave another law or no suspension")
        };
        hprintln!(
            "identify_hc k_bits=0x{:08x} n_bits=0x{:08x} lambda_bits=0x{:08x} f_n_bits=0x{:08x} zeta_bits=0x{:08x} fit_bits=0x{:08x}",
            stiffness.to_bits(),
            exponent.to_bits(),
            lambda_s_m.to_bits(),
            sus.natural_freq_hz.to_bits(),
            sus.damping_ratio.to_bits(),
            id.fit_ratio.to_bits()
        );
        hprintln!("insns identify_hc={}", identify_hc_insns);
        hprintln!("stack identify_hc_bytes={}", identify_hc_stack);

        // 2. One integrator step (embedded settings, at the operating point, over 20 periods).
        let params = RigId::Wires.preset();
        let settings = SimSettings::embedded();
        let ratio = params.ratio_from_freq_hz(f64::from(p.target_hz));
        let Ok(phases) = PhaseTable::<f32>::new(settings.steps.steps_per_period) else {
            fail("the embedded profile's N has no phase table")
        };
        let Ok(mut sim) = simulator_at::<f32>(&params, 0.0, ratio, &settings, &phases) else {
            fail("simulator_at rejected the operating point")
        };
        let mut ignore = |_: &shared::integrate::StepSample<f32>| {};
        for _ in 0..10 * 32 {
            sim.step(&mut ignore); // past the transient
        }
        let (mut step_max, mut step_sum, mut rk4) = (0u64, 0u64, 0u64);
        let n_steps = 20 * 32;
        for _ in 0..n_steps {
            let before = sim.rk4_steps();
            let t = now();
            sim.step(&mut ignore);
            let d = now().saturating_sub(t + overhead);
            rk4 += sim.rk4_steps() - before;
            step_max = step_max.max(d);
            step_sum += d;
        }
        hprintln!(
            "insns step_mean={} step_max={} rk4_per_step={}",
            insns(step_sum / n_steps),
            insns(step_max),
            rk4 as f32 / n_steps as f32
        );

        // 3. One sampling-task call: the controller tracking at the target with a toy impact
        //    train (one 1.2 ms half-sine of 96 N per cycle), mean and worst over 20 s.
        let Ok(mut c) = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0) else {
            fail("controller configuration rejected")
        };
        if let Some(req) = c.take_model_request() {
            c.set_prediction(req.generation, Ok::<Prediction, _>(p));
        }
        let _ = c.execute(Command::Stream(true));
        let _ = c.execute(Command::Start);
        let sensor = SensorChain::default();
        let (mut worst, mut sum, mut n, mut in_cycle) = (0u64, 0u64, 0u64, 0u32);
        for i in 0..250_000u64 {
            let t_in = in_cycle as f32 * 1e-4 - 0.03;
            let force = if (0.0..=0.0012).contains(&t_in) {
                96.0 * libm::sinf(core::f32::consts::PI * t_in / 0.0012)
            } else {
                0.0
            };
            let code = libm::roundf(sensor.code_of(force)) as u16;
            let cycles = c.cycles();
            let t = now();
            let _ = c.on_sample(Ok(code), (i + 1) * 100);
            let d = now().saturating_sub(t + overhead);
            if i >= 50_000 {
                worst = worst.max(d);
                sum += d;
                n += 1;
            }
            in_cycle = if c.cycles() != cycles {
                0
            } else {
                in_cycle + 1
            };
            // The console service takes the telemetry records (outside the measurement).
            while c.pop_async().is_some() {}
        }
        let worst = insns(worst);
        hprintln!("insns sample_mean={} sample_max={}", insns(sum / n), worst);

        // 4. The pendulum's sin/cos three ways, over 1,024 angles in [−0.5, 0.5] rad (the wire
        //    rig's range): instructions per (sin, cos) pair and the largest error against f64
        //    libm. The model's own polynomial (`Real::sin_cos`), `libm`'s `sinf`/`cosf`, and
        //    `micromath`'s approximations (docs/model.md, "Dependencies").
        let angle = |i: u32| -0.5 + i as f32 / 1023.0;
        let measure = |name: &str, f: &dyn Fn(f32) -> (f32, f32)| {
            let t = now();
            for i in 0..1024u32 {
                core::hint::black_box(f(core::hint::black_box(angle(i))));
            }
            let per_call = insns(now().saturating_sub(t + overhead)) / 1024;
            let err = (0..1024u32)
                .map(|i| {
                    let x = angle(i);
                    let (s, c) = f(x);
                    let xs = f64::from(x);
                    (f64::from(s) - libm::sin(xs))
                        .abs()
                        .max((f64::from(c) - libm::cos(xs)).abs())
                })
                .fold(0.0f64, f64::max);
            hprintln!("math sin_cos {} insns={} max_err={:e}", name, per_call, err);
        };
        measure("model", &|x| <f32 as shared::Real>::sin_cos(x));
        measure("libm", &|x| (libm::sinf(x), libm::cosf(x)));
        measure("micromath", &|x| {
            use micromath::F32Ext;
            (x.sin(), x.cos())
        });
        measure("empty", &|x| (x, x));
        hprintln!(
            "state={} fault={}",
            c.state().token(),
            c.fault().map_or("none", |f| f.token())
        );
        hprintln!(
            "stack_high_water_bytes={} stack_size_bytes={}",
            crate::stack::high_water_bytes().max(hwm),
            crate::stack::size_bytes()
        );

        let ok = predict_insns <= PREDICT_BUDGET
            && stored_insns <= PREDICT_BUDGET
            && identify_insns <= IDENTIFY_BUDGET
            && identify_hc_insns <= IDENTIFY_HC_BUDGET
            && worst <= SAMPLE_BUDGET
            && c.fault().is_none();
        hprintln!("budgets {}", if ok { "met" } else { "EXCEEDED" });
        debug::exit(if ok {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
        halt()
    }

    fn fail(msg: &str) -> ! {
        hprintln!("error: {}", msg);
        debug::exit(debug::EXIT_FAILURE);
        halt()
    }

    fn halt() -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        hprintln!("panic: {}", info);
        debug::exit(debug::EXIT_FAILURE);
        halt()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("qemu-check runs on the MCU target under QEMU: see tests/tests/qemu.rs");
}

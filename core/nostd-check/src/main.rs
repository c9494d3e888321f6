//! A `no_std`, `no_main` program that runs the core's executive over the shipped frame table
//! for one major frame. It exists to be linked: see Cargo.toml.
#![no_std]
#![no_main]

use core::cell::Cell;
use core::panic::PanicInfo;
use skyframe_core::comm::{Queue, Sink};
use skyframe_core::executive::{Clock, Executive, FrameRecord, Task, TaskContext, TaskFault};
use skyframe_core::link::auth::{CommandGate, GateConfig, LinkKey};
use skyframe_core::link::frame::{Envelope, MAX_DATAGRAM_LEN, encode_datagram};
use skyframe_core::link::messages::{Command, Message};
use skyframe_core::link::params::ParamTable;
use skyframe_core::schedule::{SHIPPED, SHIPPED_TASKS};

// On a hosted target the C library still starts the process and provides memcpy/memset.
#[link(name = "c")]
unsafe extern "C" {}

/// The precompiled `core` carries unwind tables that name this symbol even with
/// `panic = "abort"`; nothing ever calls it.
#[unsafe(no_mangle)]
pub extern "C" fn rust_eh_personality() {}

#[panic_handler]
fn panic(_info: &PanicInfo) -> ! {
    loop {}
}

/// A clock that ticks 1 µs per reading: enough to exercise the executive's arithmetic.
struct TickClock(Cell<u64>);

impl Clock for TickClock {
    fn now_ns(&self) -> u64 {
        let t = self.0.get() + 1_000;
        self.0.set(t);
        t
    }
}

struct Nop;

impl Task for Nop {
    fn init(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }
    fn step(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }
}

/// Entry point called by the C runtime (libc's crt0 still starts the process on a host).
#[unsafe(no_mangle)]
pub extern "C" fn main(_argc: i32, _argv: *const *const u8) -> i32 {
    let clock = TickClock(Cell::new(0));
    let mut nops: [Nop; SHIPPED_TASKS] = [const { Nop }; SHIPPED_TASKS];
    let mut tasks: [&mut dyn Task; SHIPPED_TASKS] = nops.each_mut().map(|t| t as &mut dyn Task);
    let mut queue: Queue<FrameRecord, 4> = Queue::new();
    let (mut producer, mut consumer) = queue.split();
    let mut executive = Executive::new(&SHIPPED, &clock);
    if executive.start(&mut tasks, 0).is_err() {
        return 1;
    }
    let mut frames = 0;
    for _ in 0..SHIPPED.minor_frames() {
        executive.run_frame(&mut tasks, &mut producer as &mut dyn Sink<FrameRecord>);
        while consumer.dequeue().is_some() {
            frames += 1;
        }
    }
    executive.shutdown(&mut tasks);
    if frames != SHIPPED.minor_frames() {
        return 2;
    }
    if stop_command_passes_the_gate() { 0 } else { 3 }
}

/// The link without std: sign a Stop as a ground station would, check it as the vehicle does.
fn stop_command_passes_the_gate() -> bool {
    let key = LinkKey::new([7; 32]);
    let envelope = Envelope {
        vehicle_id: 1,
        sender_id: 1,
        run_id: 42,
        sequence: 1,
        t_ns: 1_000,
    };
    let mut datagram = [0u8; MAX_DATAGRAM_LEN];
    let Ok(len) = encode_datagram(
        &envelope,
        &Message::Command(Command::Stop),
        Some(&key),
        &mut datagram,
    ) else {
        return false;
    };
    let mut gate = CommandGate::new(
        key,
        GateConfig {
            vehicle_id: 1,
            run_id: 42,
            task_count: SHIPPED_TASKS,
        },
    );
    let params = ParamTable::new();
    matches!(
        datagram.get(..len).map(|d| gate.accept(d, 2_000, &params)),
        Some(Ok(accepted)) if accepted.command == Command::Stop
    )
}

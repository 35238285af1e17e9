//! The training hot path does not allocate: over many environment steps with updates, the
//! only heap allocations are matrix products' buffers, at most one per product
//! (matrixmultiply's `sgemm` packs its operands on every call; `nn::gemm_unpacked` grows its
//! per-thread copy of a transposed operand once).

mod sac_common;

use sac_common::PointReach;
use smirl::nn::gemm;
use smirl::rl::sac::{EnvReward, SacConfig, SacTrainer};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct CountingAllocator;

thread_local! {
    // Per thread, so that allocations by the test harness's other threads (its progress
    // notices under load, for one) are not counted against the training loop.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

fn count() {
    // try_with: the slot may be gone while a thread is being torn down.
    let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
}

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn steps_with_updates_allocate_at_most_once_per_matrix_product() {
    let config = SacConfig {
        hidden: vec![32, 32],
        batch_size: 64,
        warmup_steps: 100,
        update_after: 100,
        ..SacConfig::default()
    };
    let mut env = PointReach::new(20);
    let mut trainer = SacTrainer::new(&config, 2, 1, 1).unwrap();
    trainer
        .train(&mut env, &mut EnvReward, 150, |_| {})
        .unwrap();
    let (_, shapes) = gemm::trace(|| trainer.step(&mut env, &mut EnvReward).unwrap());
    let gemms_per_step = shapes.len();
    assert!(gemms_per_step > 30, "{gemms_per_step} products per step");

    let steps = 200; // crosses ten episode boundaries
    let before = allocations();
    trainer
        .train(&mut env, &mut EnvReward, steps, |_| {})
        .unwrap();
    let allocations = allocations() - before;
    eprintln!(
        "{allocations} allocations, {} matrix products",
        steps as usize * gemms_per_step
    );
    assert!(
        allocations <= steps as usize * gemms_per_step,
        "{allocations} allocations in {steps} steps with {gemms_per_step} matrix products each"
    );
}

//! The integration tests that can share a process, as one test binary.
//!
//! Why one binary: every test binary is a separate link with (thin) LTO of
//! the whole dependency tree, repeated for the host and two ARM targets in
//! CI, and a binary of one or two long tests leaves the second core idle.
//! Merged, the harness runs every test here in parallel. The tests that
//! count the whole process's allocations (`tests/alloc_free.rs`,
//! `tests/soak.rs`) need a process of their own and stay separate, as does
//! `tests/sinks.rs`, which cross/vm-test.sh runs on a real ARM kernel.
//!
//! Run one module: `cargo test --release --test suite detect_sim::`.

// Counts allocations per thread for the checks that a stage allocates
// nothing (`thread_allocations()`); other tests running at the same time do
// not disturb a per-thread count.
#[global_allocator]
static ALLOCATOR: stature::alloc_count::CountingAlloc = stature::alloc_count::CountingAlloc;

#[path = "../common/mod.rs"]
mod common;
#[path = "../detect_support/mod.rs"]
mod detect_support;

mod board_profiles;
mod classify_alloc;
mod classify_eval;
mod classify_golden;
mod cli;
mod config_table;
mod core_accuracy;
mod detect_pets;
mod detect_sim;
mod detect_synthetic;
mod faults;
mod fuzz_corpus;
mod geometry_props;
mod live_accuracy;
mod mqtt;
mod sim_alloc;
mod sim_geometry;
mod snapshot;
mod state_lock;

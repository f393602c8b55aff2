//! `crowd`: the crowd-patches asset compiler's command line.

use clap::Parser;
use std::process::ExitCode;

/// mimalloc, not glibc's malloc: the stages allocate and free many small vectors on every
/// thread (a fifth of stage 3 was glibc's `malloc`), and whole-world tables of a gigabyte that
/// glibc hands back to the kernel at once, so the next stage pays the first-touch page faults
/// again. Measured on painting's whole build (BENCHMARKS.md).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

unsafe extern "C" {
    /// mimalloc's option setter (`mimalloc.h`); the `mimalloc` crate exposes it only with a
    /// feature whose dependency is not one we otherwise need.
    fn mi_option_set(option: std::ffi::c_int, value: std::ffi::c_long);
}

/// `mi_option_purge_delay` in `mimalloc.h`'s `mi_option_t` (15 in both the v2 and the v3
/// header that `libmimalloc-sys` 0.1.49, pinned by `Cargo.lock`, builds; read it again there
/// when that crate moves).
const MI_OPTION_PURGE_DELAY: std::ffi::c_int = 15;
/// Freed memory goes back to the kernel after this long unused, ms (the v3 default),
/// in a build split over processes: a stage's tables freed and the next stage's allocated
/// within a second reuse the same pages, and a part's peak stays what sizes its jobs.
const PURGE_DELAY_SPLIT_MS: std::ffi::c_long = 1000;
/// The same in any other command: never (mimalloc's -1), so that no page a build freed is
/// handed back and touched fresh again. On the machines this project is built on (virtual,
/// their memory taken back by the host once the guest frees it) a fresh page costs several
/// times a reused one: touching a fresh gigabyte took 2.4 s against 0.5 s reused. Kept ten
/// seconds, painting's build from nothing took 543,000-621,000 page faults; kept for good,
/// 359,000-376,000 (about its peak), 0.4-1.2 s faster, at a peak of 1.44-1.51 GB against
/// 1.38-1.54 GB: a stage's tables are made in the room the last one freed. The brush stroke:
/// 4.38-4.46 s against 4.75-5.48 s (BENCHMARKS.md, issue 20's twenty-first part).
const PURGE_DELAY_MS: std::ffi::c_long = -1;

/// Asks Linux not to back this process's memory with transparent huge pages. mimalloc asks
/// for them on its arenas; the kernel then zeroes 2 MiB at the first touch of any byte of
/// it, and the stages touch their tables sparsely: on painting's build that zeroing was an
/// eighth of all CPU time (9-12 s of system time, 7 s without; BENCHMARKS.md). Best effort:
/// where the call fails, the build is as correct, only slower.
#[cfg(target_os = "linux")]
fn no_transparent_huge_pages() {
    // SAFETY: `PR_SET_THP_DISABLE` takes one integer argument (the rest must be 0) and only
    // sets a flag of this process's memory map.
    unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0) };
}

#[cfg(not(target_os = "linux"))]
fn no_transparent_huge_pages() {}

fn main() -> ExitCode {
    no_transparent_huge_pages();
    let cli = crowd::cli::Cli::parse();
    let delay = match cli.is_split() {
        true => PURGE_DELAY_SPLIT_MS,
        false => PURGE_DELAY_MS,
    };
    // SAFETY: sets one of mimalloc's documented options to a documented value; it takes
    // effect on the next purge.
    unsafe { mi_option_set(MI_OPTION_PURGE_DELAY, delay) };
    let result = crowd::cli::run(cli);
    // The files a build replaced are removed in the background: none is left behind.
    crowd_core::files::wait_for_retired();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            crowd::ui::say(format!("error: {err}"));
            for cause in err.chain().skip(1) {
                crowd::ui::say(format!("  caused by: {cause}"));
            }
            // What the codes mean: `crowd::cli::EXIT_CODES`.
            if err.downcast_ref::<crowd::cli::Broken>().is_some() {
                ExitCode::from(3)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

//! Progress bars and messages: shown on a terminal, quiet otherwise or with `--quiet`.

use crowd_core::Progress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// How much the command says while it works.
#[derive(Debug, Clone, Copy)]
pub struct Ui {
    pub quiet: bool,
}

impl Ui {
    /// A line for a person, on stderr (stdout is kept for reports and JSON).
    pub fn say(&self, message: impl AsRef<str>) {
        if !self.quiet {
            say(message);
        }
    }

    /// A progress bar for one stage.
    pub fn stage_bar(&self, stage: &str) -> StageBar {
        let bar = if self.quiet || !std::io::stderr().is_terminal() {
            ProgressBar::hidden()
        } else {
            let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
            bar.set_style(
                ProgressStyle::with_template("{prefix:>8} [{bar:40.cyan/blue}] {pos}/{len} {msg}")
                    .expect("a valid template")
                    .progress_chars("=> "),
            );
            bar
        };
        bar.set_prefix(stage.to_string());
        StageBar(bar)
    }
}

/// An indicatif bar that stages drive through [`Progress`].
pub struct StageBar(ProgressBar);

impl Progress for StageBar {
    fn begin(&self, phase: &str, total: u64) {
        self.0.set_message(phase.to_string());
        self.0.set_position(0);
        self.0.set_length(total);
    }

    fn advance(&self, steps: u64) {
        self.0.inc(steps);
    }
}

impl Drop for StageBar {
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

/// Writes a command's results to stdout. A reader that stopped reading (`crowd report --json |
/// head`) ends the output, as for any Unix tool: the rest is dropped and the command succeeds,
/// instead of panicking on the closed pipe as `print!` does.
pub fn out(text: impl AsRef<str>) -> std::io::Result<()> {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(text.as_ref().as_bytes())
        .and_then(|()| stdout.flush())
    {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other,
    }
}

/// A line on stderr. A reader gone (`crowd build 2>&1 | head -1`) loses the lines, not the
/// build: `eprintln!` would panic halfway through it.
pub fn say(message: impl AsRef<str>) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{}", message.as_ref());
}

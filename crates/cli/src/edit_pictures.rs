//! The pictures of `crowd edit`: the descent per iteration, the trajectories before and after
//! (top views, as the paper's figures), and for `flow` the per-step comparison of Figure 5.

use anyhow::Result;
use crowd_edit::experiments::{Mark, Report, positions_at};
use crowd_render::line_colour;
use crowd_render::plot::{Curve, Outline, TopView, plot, side_by_side, top_view};
use crowd_render::save_png;
use glam::DVec2;
use image::Rgb;
use std::path::Path;

/// What the pictures show, for the README beside them.
pub const LEGEND: &str = "iterations.png: left, the cost J per iteration (black, log scale, \
one gray line per decade); middle, each constraint's RMS per iteration (one colour each, linear \
from 0); right (when the experiment has them), its own figures per iteration (vorticity: mean \
arrival time per group). trajectories.png: top views before (left) and after (right) the edit; \
thin lines are trajectories (one colour per group), discs are the characters at the \
constraint's time (the area's colour for density), rings the targets, outlined rectangles the \
constrained areas, dark gray the obstacles. per-step.png (flow): normalised RMS per time step \
of the simulation (blue), advection (orange), simulation + advection (green) and the edit \
(red), from 0 to the largest value";

const INK: Rgb<u8> = Rgb([20, 20, 20]);

pub fn write(report: &Report, dir: &Path) -> Result<()> {
    save_png(&iterations(report), &dir.join("iterations.png"))?;
    save_png(&trajectories(report), &dir.join("trajectories.png"))?;
    if !report.per_step.is_empty() {
        let curves: Vec<Curve> = report
            .per_step
            .iter()
            .enumerate()
            .map(|(k, s)| Curve {
                values: &s.values,
                colour: line_colour(k),
            })
            .collect();
        save_png(&plot(&curves, false, 720, 360), &dir.join("per-step.png"))?;
    }
    Ok(())
}

fn iterations(report: &Report) -> image::RgbImage {
    let column = |f: &dyn Fn(&crowd_edit::experiments::Row) -> f64| -> Vec<f64> {
        report.rows.iter().map(f).collect()
    };
    let cost = column(&|r| r.iteration.cost.total());
    let mut panels = vec![plot(
        &[Curve {
            values: &cost,
            colour: INK,
        }],
        true,
        420,
        300,
    )];
    let residuals: Vec<Vec<f64>> = (0..report.setup.problem.constraints.len())
        .map(|k| column(&|r| r.iteration.residuals[k]))
        .collect();
    panels.push(plot(&curves(&residuals), false, 420, 300));
    if !report.extra_columns.is_empty() {
        let extra: Vec<Vec<f64>> = (0..report.extra_columns.len())
            .map(|k| column(&|r| r.extra[k]))
            .collect();
        panels.push(plot(&curves(&extra), false, 420, 300));
    }
    side_by_side(&panels, 12)
}

fn curves(series: &[Vec<f64>]) -> Vec<Curve<'_>> {
    series
        .iter()
        .enumerate()
        .map(|(k, values)| Curve {
            values,
            colour: line_colour(k),
        })
        .collect()
}

/// The instants the pictures show the characters at, with a colour for each.
fn instants(report: &Report) -> Vec<(f64, Option<Rgb<u8>>)> {
    let marks = &report.setup.marks;
    if marks.is_empty() {
        return vec![(report.setup.problem.timeline.duration() / 2.0, None)];
    }
    let areas = marks
        .iter()
        .filter(|m| matches!(m, Mark::Area { .. }))
        .count();
    let mut out: Vec<(f64, Option<Rgb<u8>>)> = marks
        .iter()
        .enumerate()
        .map(|(k, m)| match m {
            Mark::Point { time, .. } | Mark::Targets { time, .. } => (*time, None),
            Mark::Area { from, to, .. } => {
                ((from + to) / 2.0, (areas > 1).then(|| line_colour(k + 3)))
            }
        })
        .collect();
    out.dedup_by(|a, b| a.0 == b.0);
    out
}

fn trajectories(report: &Report) -> image::RgbImage {
    let p = &report.setup.problem;
    let world = &p.model.world;
    let obstacles: Vec<(DVec2, DVec2)> = world.obstacles.iter().map(|o| (o.min, o.max)).collect();
    let mut outlines = Vec::new();
    let mut targets = Vec::new();
    for (k, m) in report.setup.marks.iter().enumerate() {
        match m {
            Mark::Area { rect, .. } => outlines.push(Outline {
                min: rect.min,
                max: rect.max,
                colour: line_colour(k + 3),
            }),
            Mark::Point { at, .. } => targets.push((*at, 0.3, INK, false)),
            Mark::Targets { points, .. } => {
                targets.extend(points.iter().map(|q| (*q, 0.3, INK, false)))
            }
        }
    }
    let extent = world.bounds.max - world.bounds.min;
    let px_per_m = (700.0 / extent.x.max(extent.y)).clamp(6.0, 24.0);
    let view = |states: &[f64]| {
        let frames: Vec<Vec<DVec2>> = (0..=p.timeline.steps)
            .map(|k| positions_at(p, states, k))
            .collect();
        let mut paths = Vec::new();
        for (g, (_, members)) in report.setup.groups.iter().enumerate() {
            let colour = lighter(line_colour(g));
            for &i in members {
                paths.push((frames.iter().map(|f| f[i]).collect(), colour));
            }
        }
        let mut discs = targets.clone();
        for (t, colour) in instants(report) {
            let pos = &frames[p.timeline.step_at(t)];
            for (g, (_, members)) in report.setup.groups.iter().enumerate() {
                for &i in members {
                    let c = colour.unwrap_or(line_colour(g));
                    discs.push((pos[i], p.model.characters[i].radius, c, true));
                }
            }
        }
        top_view(
            &TopView {
                min: world.bounds.min,
                max: world.bounds.max,
                obstacles: &obstacles,
                outlines: &outlines,
                paths: &paths,
                discs: &discs,
            },
            px_per_m,
        )
    };
    side_by_side(&[view(&report.before), view(&report.after)], 12)
}

fn lighter(c: Rgb<u8>) -> Rgb<u8> {
    let mix = |v: u8| ((v as u16 + 2 * 255) / 3) as u8;
    Rgb([mix(c.0[0]), mix(c.0[1]), mix(c.0[2])])
}

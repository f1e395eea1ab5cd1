//! The generate screen's coverage of the initial scenes: support coverage against uniformly spread
//! scenes, histograms per object coordinate, attempts per source demo; beside another run's when
//! comparing.

use std::collections::BTreeMap;

use egui_plot::{Bar, BarChart, Plot};
use mimicgen_engine::Pose;
use mimicgen_engine::coverage::{Coordinate, Coverage, Dimension, coverage, uniform_support_coverage};
use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};

use crate::model::RunState;
use crate::protocol::{AttemptRow, OpenedRun};

use crate::style::{FAILURE, SUCCESS};

/// Bins per coordinate of the support coverage (the paper's appendix uses 3).
const SUPPORT_BINS: usize = 3;
/// Bins per coordinate of the histograms.
const HISTOGRAM_BINS: usize = 10;

/// The initial scenes of `rows` as object poses (for the engine's coverage analysis).
fn scenes<'a>(rows: impl Iterator<Item = &'a AttemptRow>) -> Vec<BTreeMap<String, Pose>> {
    rows.map(|r| {
        r.objects
            .iter()
            .map(|o| {
                (
                    o.name.clone(),
                    pose_from_parts(Vec3::new(o.position[0], o.position[1], o.position[2]), Rot::from_axis_angle(&Vec3::z_axis(), o.yaw)),
                )
            })
            .collect()
    })
    .collect()
}

/// Support coverage of the run's initial scenes (all, successes, failures) against uniformly
/// spread scenes, and per-coordinate histograms over the reset region, successes and failures
/// stacked: the numbers `mimicgen coverage` prints, from the same function. With a run to compare
/// with, its numbers and histograms follow on a second row.
pub(crate) fn coverage_view(ui: &mut egui::Ui, run: &RunState, compare: Option<&OpenedRun>, cache: &mut Vec<CoverageFigures>) {
    if run.dimensions.is_empty() || run.rows.is_empty() {
        return;
    }
    let mut blocks = vec![("this run".to_owned(), run.rows.as_slice(), run.dimensions.as_slice())];
    if let Some(other) = compare {
        let name = other.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        blocks.push((format!("{name} ({} {})", other.info.task, other.info.variant), &other.rows, &other.dimensions));
    }
    // The figures are computed when a block's rows change (a run's attempt arrives), not every
    // frame: with thousands of attempts the binning costs more than drawing.
    cache.retain(|c| blocks.iter().any(|(title, rows, _)| c.title == *title && c.key == CoverageFigures::key_of(rows)));
    for (title, rows, dimensions) in &blocks {
        if !cache.iter().any(|c| c.title == *title) {
            cache.push(CoverageFigures::compute(title, rows, dimensions));
        }
    }
    egui::CollapsingHeader::new("Coverage of the initial scenes").default_open(true).show(ui, |ui| {
        for (title, rows, _) in &blocks {
            if let Some(figures) = cache.iter().find(|c| c.title == *title) {
                coverage_block(ui, figures, rows);
            }
        }
    });
}

/// A coverage block's numbers and histograms, kept until its rows change.
#[derive(Debug, Clone)]
pub struct CoverageFigures {
    title: String,
    /// What the rows were: how many, how many succeeded, the last attempt's index, the first
    /// scene's first coordinate (another run with as many rows differs there).
    key: (usize, usize, Option<u64>, Option<u64>),
    /// The line of support coverages (`None`: too few scenes to bin).
    summary: Option<String>,
    /// Per-coordinate histograms of the successes and of the failures.
    histograms: Option<(Coverage, Coverage)>,
}

impl CoverageFigures {
    fn key_of(rows: &[AttemptRow]) -> (usize, usize, Option<u64>, Option<u64>) {
        let first = rows.first().and_then(|r| r.objects.first()).map(|o| o.position[0].to_bits());
        (rows.len(), rows.iter().filter(|r| r.success).count(), rows.last().map(|r| r.index), first)
    }

    fn compute(title: &str, rows: &[AttemptRow], dimensions: &[Dimension]) -> Self {
        let all = scenes(rows.iter());
        let good = scenes(rows.iter().filter(|r| r.success));
        let bad = scenes(rows.iter().filter(|r| !r.success));
        let support = |s: &[BTreeMap<String, Pose>]| coverage(s, dimensions, SUPPORT_BINS).ok();
        let summary = match (support(&all), support(&good), support(&bad)) {
            (Some(c_all), Some(c_good), Some(c_bad)) => {
                let uniform = uniform_support_coverage(c_all.joint_bins_total, all.len());
                #[allow(clippy::cast_precision_loss)]
                let rate = 100.0 * good.len() as f64 / all.len().max(1) as f64;
                Some(format!(
                    "{title}: {} scenes, {} successes ({rate:.1} % of the attempts kept); support coverage ({SUPPORT_BINS} bins per coordinate, {} joint bins): all {:.1} % (uniformly spread scenes: {:.1} %), successes {:.1} %, failures {:.1} %",
                    all.len(),
                    good.len(),
                    c_all.joint_bins_total,
                    100.0 * c_all.support_coverage(),
                    100.0 * uniform,
                    100.0 * c_good.support_coverage(),
                    100.0 * c_bad.support_coverage(),
                ))
            }
            _ => None,
        };
        let histograms = coverage(&good, dimensions, HISTOGRAM_BINS).ok().zip(coverage(&bad, dimensions, HISTOGRAM_BINS).ok());
        Self { title: title.to_owned(), key: Self::key_of(rows), summary, histograms }
    }
}

fn coverage_block(ui: &mut egui::Ui, figures: &CoverageFigures, rows: &[AttemptRow]) {
    let (Some(summary), Some((h_good, h_bad))) = (&figures.summary, &figures.histograms) else { return };
    let title = figures.title.as_str();
    ui.label(summary);
    let mut charts = vec![source_demo_chart(title, rows)];
    for (k, ((dim, good), bad)) in h_good.dimensions.iter().zip(&h_good.histograms).zip(&h_bad.histograms).enumerate() {
        #[allow(clippy::cast_precision_loss)]
        let width = (dim.high - dim.low) / HISTOGRAM_BINS as f64;
        #[allow(clippy::cast_precision_loss)]
        let bars = |h: &[usize]| -> Vec<Bar> {
            h.iter().enumerate().map(|(b, &n)| Bar::new(dim.low + (b as f64 + 0.5) * width, n as f64).width(width * 0.9)).collect()
        };
        let succeeded = BarChart::new("successes", bars(good)).color(SUCCESS);
        let failed = BarChart::new("failures", bars(bad)).color(FAILURE).stack_on(&[&succeeded]);
        let coordinate = match dim.coordinate {
            Coordinate::X => "x (m)",
            Coordinate::Y => "y (m)",
            Coordinate::Yaw => "yaw (rad)",
        };
        charts.push(SmallBars {
            id: Plot::new(("coverage", title, k)),
            x_label: format!("{} {coordinate}", dim.object),
            succeeded,
            failed,
        });
    }
    // Rows of as many charts as fit the width (a browser beside the 3D view is narrow): a chart
    // reaching past the edge would widen everything drawn after it.
    let spacing = ui.spacing().item_spacing.x;
    let available = ui.available_width();
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)]
    let per_row = (((available + spacing) / (SMALL_BARS_MIN_WIDTH + spacing)).floor().max(1.0) as usize).min(charts.len());
    #[allow(clippy::cast_precision_loss)]
    let width = ((available + spacing) / per_row as f32 - spacing).clamp(SMALL_BARS_MIN_WIDTH.min(available), SMALL_BARS_MAX_WIDTH);
    let mut charts = charts.into_iter().peekable();
    while charts.peek().is_some() {
        ui.horizontal(|ui| {
            for chart in charts.by_ref().take(per_row) {
                chart.show(ui, width);
            }
        });
    }
}

/// The narrowest and widest a coverage chart is drawn.
const SMALL_BARS_MIN_WIDTH: f32 = 110.0;
const SMALL_BARS_MAX_WIDTH: f32 = 240.0;

/// Which source demos the kept attempts used (any subtask), successes and failures stacked: the
/// paper notes successes can come very unevenly from the sources.
fn source_demo_chart(title: &str, rows: &[AttemptRow]) -> SmallBars<'static> {
    let demos = rows.iter().flat_map(|r| r.sources.iter().copied()).max().map_or(0, |d| d + 1);
    let (mut good, mut bad) = (vec![0usize; demos], vec![0usize; demos]);
    for r in rows {
        let mut used = r.sources.clone();
        used.sort_unstable();
        used.dedup();
        // `demos` is one past the largest source, so every slot exists.
        for d in used {
            if let Some(count) = if r.success { &mut good } else { &mut bad }.get_mut(d) {
                *count += 1;
            }
        }
    }
    #[allow(clippy::cast_precision_loss)]
    let bars =
        |counts: &[usize]| -> Vec<Bar> { counts.iter().enumerate().map(|(d, &n)| Bar::new(d as f64, n as f64).width(0.7)).collect() };
    let succeeded = BarChart::new("successes", bars(&good)).color(SUCCESS);
    let failed = BarChart::new("failures", bars(&bad)).color(FAILURE).stack_on(&[&succeeded]);
    SmallBars { id: Plot::new(("sources", title)), x_label: "source demo".to_owned(), succeeded, failed }
}

/// One of the coverage row's small charts: successes and failures stacked, fixed in place.
struct SmallBars<'a> {
    id: Plot<'a>,
    x_label: String,
    succeeded: BarChart,
    failed: BarChart,
}

impl SmallBars<'_> {
    fn show(self, ui: &mut egui::Ui, width: f32) {
        let Self { id, x_label, succeeded, failed } = self;
        id.width(width).height(110.0).x_axis_label(x_label).show_axes([true, false]).allow_drag(false).allow_scroll(false).show(
            ui,
            |plot| {
                plot.bar_chart(succeeded);
                plot.bar_chart(failed);
            },
        );
    }
}

//! The scene × method table of a set of comparisons (\[KL06\] §8, Fig. 6's metrics), as
//! Markdown: one row per scene and method, the lowest relative RMSE of each scene in bold,
//! then each method's mean over the scenes that have it and its ratio to the best engine
//! baseline's mean ([`lightvol_sampler::baselines`]). Comparisons that read the methods
//! several ways (`compare --lookup`, [`crate::reads`]) give the scene rows of the first
//! way and one column block of means per way, each divided by the best engine baseline
//! read the same way.

use std::fmt::Write as _;

/// One method's figures on one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct TableRow {
    /// The scene's label.
    pub scene: String,
    /// The compared entry (`doi`, `point+apv`, ...).
    pub method: String,
    /// How it was read (`lightvol`, `three`, ..., `native`; [`crate::ReadAs`]).
    pub lookup: String,
    /// Relative RMSE on the plate ([`crate::metrics::Metrics::rel_rmse`]).
    pub rel_rmse: f64,
    /// Share of plate points near geometry that are too dark.
    pub too_dark_near: f64,
    /// Share of plate points that are too bright.
    pub too_bright: f64,
    /// Rays the bake traced.
    pub rays: u64,
    /// Seconds the bake took.
    pub seconds: f64,
}

/// Whether `method` is one of the engines' leak fixes (`point+validity`, `point+apv`, ...).
#[must_use]
pub fn is_engine_baseline(method: &str) -> bool {
    lightvol_sampler::method::Baseline::from_name(method).is_some()
}

/// A method's name, its mean relative RMSE and the number of scenes it was run on.
pub type MethodMean = (String, f64, usize);

/// Each method's mean relative RMSE over the scenes it was run on, in first-seen order.
#[must_use]
pub fn method_means(rows: &[TableRow]) -> Vec<MethodMean> {
    let mut out: Vec<MethodMean> = Vec::new();
    for r in rows {
        match out.iter_mut().find(|(m, _, _)| *m == r.method) {
            Some((_, sum, n)) => {
                *sum += r.rel_rmse;
                *n += 1;
            }
            None => out.push((r.method.clone(), r.rel_rmse, 1)),
        }
    }
    for (_, sum, n) in &mut out {
        *sum /= *n as f64;
    }
    out
}

/// The lowest mean among the engine baselines of `means` (infinite when there is none).
fn best_baseline(means: &[MethodMean]) -> f64 {
    means.iter().filter(|(m, _, _)| is_engine_baseline(m)).map(|(_, v, _)| *v).fold(f64::INFINITY, f64::min)
}

/// `v / best` to two places, `-` without a baseline.
fn ratio(v: f64, best: f64) -> String {
    if best.is_finite() { format!("{:.2}", v / best) } else { "-".to_owned() }
}

/// The Markdown table (module docs).
#[must_use]
pub fn markdown_table(rows: &[TableRow]) -> String {
    let mut ways: Vec<&str> = Vec::new();
    for r in rows {
        if !ways.contains(&r.lookup.as_str()) {
            ways.push(&r.lookup);
        }
    }
    let first: Vec<TableRow> =
        rows.iter().filter(|r| Some(&r.lookup.as_str()) == ways.first()).cloned().collect();
    let mut s = String::from(
        "| scene | method | rel_rmse | too_dark_near | too_bright | rays | seconds |\n| --- | --- | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for r in &first {
        let best =
            first.iter().filter(|o| o.scene == r.scene).map(|o| o.rel_rmse).fold(f64::INFINITY, f64::min);
        let rmse =
            if r.rel_rmse == best { format!("**{:.3}**", r.rel_rmse) } else { format!("{:.3}", r.rel_rmse) };
        let _ = writeln!(
            s,
            "| {} | {} | {rmse} | {:.3} | {:.3} | {} | {:.2} |",
            r.scene, r.method, r.too_dark_near, r.too_bright, r.rays, r.seconds
        );
    }
    let means = method_means(&first);
    if ways.len() <= 1 {
        let best = best_baseline(&means);
        s.push_str(
            "\n| method | mean rel_rmse | scenes | / best engine baseline |\n| --- | ---: | ---: | ---: |\n",
        );
        for (m, v, n) in &means {
            let _ = writeln!(s, "| {m} | {v:.3} | {n} | {} |", ratio(*v, best));
        }
        return s;
    }
    // One block of means per way, each against its own best baseline.
    let blocks: Vec<(Vec<MethodMean>, f64)> = ways
        .iter()
        .map(|w| {
            let of: Vec<TableRow> = rows.iter().filter(|r| r.lookup == *w).cloned().collect();
            let m = method_means(&of);
            let best = best_baseline(&m);
            (m, best)
        })
        .collect();
    s.push_str("\n| method | scenes |");
    for w in &ways {
        let _ = write!(s, " {w} | / best |");
    }
    s.push_str("\n| --- | ---: |");
    for _ in &ways {
        s.push_str(" ---: | ---: |");
    }
    s.push('\n');
    let mut names: Vec<(&str, usize)> = Vec::new();
    for (block, _) in &blocks {
        for (m, _, n) in block {
            if !names.iter().any(|(o, _)| o == m) {
                names.push((m, *n));
            }
        }
    }
    for (m, n) in names {
        let _ = write!(s, "| {m} | {n} |");
        for (block, best) in &blocks {
            match block.iter().find(|(b, _, _)| b == m) {
                Some((_, v, _)) => {
                    let _ = write!(s, " {v:.3} | {} |", ratio(*v, *best));
                }
                None => s.push_str(" - | - |"),
            }
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(scene: &str, method: &str, rel_rmse: f64) -> TableRow {
        TableRow {
            scene: scene.into(),
            method: method.into(),
            lookup: "lightvol".into(),
            rel_rmse,
            too_dark_near: 0.25,
            too_bright: 0.5,
            rays: 10,
            seconds: 1.5,
        }
    }

    #[test]
    fn baselines_are_recognised_by_name() {
        assert!(is_engine_baseline("point+apv"));
        assert!(is_engine_baseline("point+ddgi"));
        assert!(!is_engine_baseline("point"));
        assert!(!is_engine_baseline("doi+lsq:0.5"));
        assert!(!is_engine_baseline("point+taylor"));
    }

    /// Means over scenes, the bold best per scene, and the ratio to the best baseline:
    /// doi (0.1 + 0.3)/2 = 0.2 against APV's (0.2 + 0.2)/2 = 0.2 and DDGI's 0.25.
    #[test]
    fn the_table_bolds_each_scenes_best_and_divides_by_the_best_baseline() {
        let rows = [
            row("a", "doi", 0.1),
            row("a", "point+apv", 0.2),
            row("a", "point+ddgi", 0.3),
            row("b", "doi", 0.3),
            row("b", "point+apv", 0.2),
            row("b", "point+ddgi", 0.2),
        ];
        let means = method_means(&rows);
        assert_eq!(means.len(), 3);
        assert!((means[0].1 - 0.2).abs() < 1e-12 && means[0].2 == 2);
        assert!((means[2].1 - 0.25).abs() < 1e-12);
        let t = markdown_table(&rows);
        assert!(t.contains("| a | doi | **0.100** | 0.250 | 0.500 | 10 | 1.50 |"), "{t}");
        assert!(t.contains("| b | point+apv | **0.200** |"), "{t}");
        assert!(t.contains("| b | point+ddgi | **0.200** |"), "{t}");
        assert!(t.contains("| doi | 0.200 | 2 | 1.00 |"), "{t}");
        assert!(t.contains("| point+ddgi | 0.250 | 2 | 1.25 |"), "{t}");
    }

    /// Several ways of reading: the scene rows are the first way's; each way's block of
    /// means is divided by the best baseline read that way: through three, doi+three
    /// (0.1 + 0.2)/2 = 0.15 against APV's (0.3 + 0.3)/2 = 0.3 gives 0.50.
    #[test]
    fn each_way_gets_its_own_block_of_means() {
        let read = |scene: &str, method: &str, lookup: &str, v: f64| TableRow {
            lookup: lookup.into(),
            ..row(scene, method, v)
        };
        let rows = [
            read("a", "doi", "lightvol", 0.1),
            read("a", "point+apv", "lightvol", 0.2),
            read("b", "doi", "lightvol", 0.1),
            read("b", "point+apv", "lightvol", 0.2),
            read("a", "doi+three", "three", 0.1),
            read("a", "point+apv", "three", 0.3),
            read("b", "doi+three", "three", 0.2),
            read("b", "point+apv", "three", 0.3),
        ];
        let t = markdown_table(&rows);
        assert!(t.contains("| method | scenes | lightvol | / best | three | / best |"), "{t}");
        assert!(t.contains("| doi | 2 | 0.100 | 0.50 | - | - |"), "{t}");
        assert!(t.contains("| point+apv | 2 | 0.200 | 1.00 | 0.300 | 1.00 |"), "{t}");
        assert!(t.contains("| doi+three | 2 | - | - | 0.150 | 0.50 |"), "{t}");
        assert!(!t.contains("| a | doi+three |"), "scene rows are the first way's: {t}");
    }
}

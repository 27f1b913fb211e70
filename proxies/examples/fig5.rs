//! [SGNS07] Fig. 5 (top left) reproduced: Frobenius error of the point-sampled (Eq. 13) and
//! averaged (Eq. 15) indirect operators against the exact one (Eq. 16-17) as functions of
//! `sin θ`, at SH orders 3 and 4; plus the Fig. 4 fit errors of `D_1` and `D_2`.
//!
//! `cargo run --release -p lightvol-proxies --example fig5 -- [-o DIR]` writes `fig5.csv`,
//! `fig5.json` and `fig5.svg` to DIR (default `fig5-out`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use lightvol_proxies::operators::{
    OperatorError, d_exact, d_paper_fit, operator_error, relative_squared_error,
};

fn write_atomic(path: &Path, text: &str) -> anyhow::Result<()> {
    lightvol_core::fs::write_atomic(path, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

fn svg(rows3: &[OperatorError], rows4: &[OperatorError]) -> String {
    let (w, h, m) = (640.0, 420.0, 60.0);
    let ymax = rows3.iter().chain(rows4).map(|r| r.point_sampled.max(r.averaged)).fold(0.0, f64::max) * 1.1;
    let x = |a: f64| m + a * (w - 1.5 * m);
    let y = |e: f64| h - m - e / ymax * (h - 1.6 * m);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="24" text-anchor="middle" font-size="14">Indirect operator error vs exact (Frobenius), [SGNS07] Fig. 5</text>"#,
        w / 2.0
    );
    // Axes and ticks.
    let _ = writeln!(s, r#"<line x1="{m}" y1="{}" x2="{}" y2="{}" stroke="black"/>"#, y(0.0), x(1.0), y(0.0));
    let _ = writeln!(s, r#"<line x1="{m}" y1="{}" x2="{m}" y2="{}" stroke="black"/>"#, y(0.0), y(ymax));
    for k in 0..=10 {
        let a = f64::from(k) / 10.0;
        let _ = writeln!(s, r#"<text x="{}" y="{}" text-anchor="middle">{a:.1}</text>"#, x(a), y(0.0) + 16.0);
    }
    for k in 0..=5 {
        let e = ymax * f64::from(k) / 5.0;
        let _ = writeln!(s, r#"<text x="{}" y="{}" text-anchor="end">{e:.2}</text>"#, m - 6.0, y(e) + 4.0);
        let _ = writeln!(s, r##"<line x1="{m}" y1="{0}" x2="{1}" y2="{0}" stroke="#ddd"/>"##, y(e), x(1.0));
    }
    let _ = writeln!(s, r#"<text x="{}" y="{}" text-anchor="middle">sin θ</text>"#, x(0.5), h - 18.0);
    let series = [
        (rows3, true, "#d62728", "point-sampled, order 3", "none"),
        (rows3, false, "#1f77b4", "averaged, order 3", "none"),
        (rows4, true, "#d62728", "point-sampled, order 4", "6,4"),
        (rows4, false, "#1f77b4", "averaged, order 4", "6,4"),
    ];
    for (i, (rows, point, color, label, dash)) in series.iter().enumerate() {
        let pts: Vec<String> = rows
            .iter()
            .map(|r| format!("{:.2},{:.2}", x(r.alpha), y(if *point { r.point_sampled } else { r.averaged })))
            .collect();
        let _ = writeln!(
            s,
            r#"<polyline fill="none" stroke="{color}" stroke-width="2" stroke-dasharray="{dash}" points="{}"/>"#,
            pts.join(" ")
        );
        let ly = m + 18.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{}" y1="{ly}" x2="{}" y2="{ly}" stroke="{color}" stroke-width="2" stroke-dasharray="{dash}"/>"#,
            m + 20.0,
            m + 50.0
        );
        let _ = writeln!(s, r#"<text x="{}" y="{}">{label}</text>"#, m + 56.0, ly + 4.0);
    }
    s.push_str("</svg>\n");
    s
}

fn main() -> anyhow::Result<()> {
    let mut out = PathBuf::from("fig5-out");
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "-o" | "--out" => out = PathBuf::from(args.next().context("-o needs a directory")?),
            other => anyhow::bail!("unknown argument {other}; usage: fig5 [-o DIR]"),
        }
    }
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let alphas: Vec<f64> = (0..=100).map(|k| f64::from(k) / 100.0).collect();
    let rows3: Vec<OperatorError> = alphas.iter().map(|&a| operator_error::<9>(a)).collect();
    let rows4: Vec<OperatorError> = alphas.iter().map(|&a| operator_error::<16>(a)).collect();
    let mut csv = String::from("sin_theta,order,point_sampled,averaged,exact_norm\n");
    for (rows, order) in [(&rows3, 3), (&rows4, 4)] {
        for r in rows.iter() {
            let _ = writeln!(
                csv,
                "{},{order},{:.9e},{:.9e},{:.9e}",
                r.alpha, r.point_sampled, r.averaged, r.exact_norm
            );
        }
    }
    let e1 = relative_squared_error(|a| d_paper_fit(a)[1], |a| d_exact(a, 3)[1], 200);
    let e2 = relative_squared_error(|a| d_paper_fit(a)[2], |a| d_exact(a, 3)[2], 200);
    let json = serde_json::json!({
        "order3": rows3,
        "order4": rows4,
        "fit_relative_squared_error": {
            "D1": {"measured": e1, "paper": 0.00016e-2},
            "D2": {"measured": e2, "paper": 0.00064e-2},
        },
    });
    write_atomic(&out.join("fig5.csv"), &csv)?;
    write_atomic(&out.join("fig5.json"), &(serde_json::to_string_pretty(&json)? + "\n"))?;
    write_atomic(&out.join("fig5.svg"), &svg(&rows3, &rows4))?;
    println!("sin θ   point(3)  averaged(3)  point(4)  averaged(4)");
    for k in (10..=100).step_by(10) {
        let (a, b) = (&rows3[k], &rows4[k]);
        println!(
            "{:.1}   {:.4}    {:.4}       {:.4}    {:.4}",
            a.alpha, a.point_sampled, a.averaged, b.point_sampled, b.averaged
        );
    }
    println!("D1 fit relative squared error {:.3e} ({:.5}%; paper 0.00016%)", e1, 100.0 * e1);
    println!("D2 fit relative squared error {:.3e} ({:.5}%; paper 0.00064%)", e2, 100.0 * e2);
    println!("wrote {}", out.display());
    Ok(())
}

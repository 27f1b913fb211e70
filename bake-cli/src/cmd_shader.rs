//! `lightvol shader`: the sampling code for engines (lightvol-gpu's `engine_shader`), in
//! WGSL, HLSL or GLSL, for the KTX2 export's texture, the native f32 layout or the brick
//! export (lightvol-gpu's `brick_shader`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, ValueEnum};
use lightvol_gpu::brick_shader::brick_shader_source;
use lightvol_gpu::engine_shader::{Language, Layout, shader_source};

/// `--lang`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum LangArg {
    /// WGSL (the source the others are translated from).
    Wgsl,
    /// HLSL (shader model 5.1), translated by naga.
    Hlsl,
    /// GLSL 4.50, translated by naga.
    Glsl,
}

/// `--layout`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum LayoutArg {
    /// The KTX2 export (`export --format ktx2`): an RGBA16F 3D texture of coefficient slabs.
    Ktx2,
    /// The native `[node][coeff][rgb]` f32 array, in a storage buffer.
    Native,
    /// The brick export (`export --format bricks`): the RGBA16F atlas and its RGBA8
    /// indirection texture.
    Bricks,
}

/// `lightvol shader`.
#[derive(Debug, Args)]
pub(crate) struct ShaderArgs {
    /// Shading language.
    #[arg(long, value_enum, default_value = "wgsl")]
    lang: LangArg,
    /// Where the coefficients live.
    #[arg(long, value_enum, default_value = "ktx2")]
    pub(crate) layout: LayoutArg,
    /// Output file (default: standard output).
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
}

/// Runs `lightvol shader`.
pub(crate) fn run(args: &ShaderArgs) -> anyhow::Result<ExitCode> {
    let lang = match args.lang {
        LangArg::Wgsl => Language::Wgsl,
        LangArg::Hlsl => Language::Hlsl,
        LangArg::Glsl => Language::Glsl,
    };
    let src = match args.layout {
        LayoutArg::Ktx2 => shader_source(lang, Layout::Ktx2),
        LayoutArg::Native => shader_source(lang, Layout::Native),
        LayoutArg::Bricks => brick_shader_source(lang),
    }
    .context("generating the sampling code")?;
    match &args.output {
        None => print!("{src}"),
        Some(p) => {
            crate::imaging::write_atomic(p, src.as_bytes())
                .with_context(|| format!("writing {}", p.display()))?;
            eprintln!("wrote {}", p.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

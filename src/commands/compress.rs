//! `chronomap compress`: FFT FreMEn with the outlier set on a uniformly sampled binary series
//! ([Krajník 2017] §III-B, §IV-A, §IV-C; `chronomap_app::compress` runs the study, this prints
//! and writes the model).

use anyhow::{Result, bail};
use chronomap_app::compress::Samples;
use chronomap_io::write_any_model;
use chronomap_models::AnyModel;

use super::{read_series, source_name};
use crate::cli::{CompressArgs, OrderArg};
use crate::outln;
use crate::output::print_json;

pub fn run(args: &CompressArgs) -> Result<()> {
    let samples = Samples::of(&source_name(&args.series), &read_series(&args.series)?)?;
    let shortest = args.shortest_period.0;
    let (order, chosen) = match args.order {
        OrderArg::Auto => {
            let chosen = samples.choose_order(shortest)?;
            if !args.json {
                outln!("{}", chosen.text())?;
            }
            (chosen.order, Some(chosen))
        }
        OrderArg::Fixed(k) => (k, None),
    };
    let test = args.test.as_ref().map(read_series).transpose()?;
    let report = samples.study(order, chosen, shortest, test.as_ref())?;
    if args.json {
        print_json(&report.json(args.output.as_deref()))?;
    } else {
        outln!("{}", report.text())?;
    }
    if let Some(path) = &args.output {
        write_any_model(path, &AnyModel::Fft(report.model.clone()))?;
        if !args.json {
            outln!("wrote {}", path.display())?;
        }
    }
    if !report.compression.series.lossless {
        bail!("reconstruction is not lossless");
    }
    Ok(())
}

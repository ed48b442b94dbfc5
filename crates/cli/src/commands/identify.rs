//! `optobus identify`: which model the device at --tcp or --serial is, from each spec's
//! fingerprint (`optobus_driver::identify`), with the evidence per model.

use optobus_driver::identify::{Finding, Identification, Verdict};
use serde_json::{json, Value as Json};

use crate::connect::Global;
use crate::error::CliError;
use crate::models;
use crate::render::{pretty, print};

pub(crate) async fn run(global: &Global) -> Result<(), CliError> {
    let Some(addressed) = global.target.addressed() else {
        return Err(
            CliError::new("identify asks a real device: give --tcp or --serial")
                .hint("`optobus simulate MODEL` serves a simulator to try it on"),
        );
    };
    if let Some(model) = &global.model {
        return Err(CliError::new(format!(
            "identify tries every model; --model {model} would only be believed"
        ))
        .hint("leave out --model; --spec FILE adds a model of your own"));
    }
    if global.slave == Some(0) {
        return Err(CliError::new(
            "`identify` needs replies, and no device answers slave 0, the broadcast address",
        )
        .hint("give the device's address with --slave, or leave it out for each model's own"));
    }
    let found = global.identify(&global.target, global.slave).await?;
    let verdict = found.verdict();
    print(&if global.json {
        pretty(&as_json(&found, &verdict))
    } else {
        text(&found, &verdict)
    });
    match verdict {
        Verdict::One(_) => Ok(()),
        other => Err(
            CliError::failed(format!("{other} the device at {addressed}"))
                .hint("the evidence per model is above; `--spec FILE` tries a model of your own"),
        ),
    }
}

fn text(found: &Identification, verdict: &Verdict) -> String {
    let mut out = format!("model: {verdict}\n");
    for evidence in &found.candidates {
        let outcome = if evidence.fits() { "fits" } else { "ruled out" };
        out.push_str(&format!(
            "{} (slave {}): {outcome}\n",
            models::name(evidence.model),
            evidence.slave
        ));
        let mut findings = evidence.findings.iter().peekable();
        while let Some(finding) = findings.next() {
            let sign = if finding.rules_out() { '-' } else { '+' };
            // Requests that answered one after another, on one line.
            let mut answered = 1;
            while is_answer(finding) && findings.next_if(|f| is_answer(f)).is_some() {
                answered += 1;
            }
            if answered > 1 {
                let after = answered - 1;
                let plural = if after == 1 { "" } else { "s" };
                out.push_str(&format!(
                    "  + {finding}, and {after} request{plural} after it\n"
                ));
            } else {
                out.push_str(&format!("  {sign} {finding}\n"));
            }
        }
    }
    out
}

fn is_answer(finding: &Finding) -> bool {
    matches!(finding, Finding::Answered { .. })
}

fn as_json(found: &Identification, verdict: &Verdict) -> Json {
    let model = match verdict {
        Verdict::One(model) => Json::from(models::name(model)),
        _ => Json::Null,
    };
    let fitting: Vec<String> = found.fitting().iter().map(|m| models::name(m)).collect();
    let candidates: Vec<Json> = found
        .candidates
        .iter()
        .map(|evidence| {
            let findings: Vec<Json> = evidence
                .findings
                .iter()
                .map(|f| json!({"rules_out": f.rules_out(), "finding": f.to_string()}))
                .collect();
            json!({
                "model": models::name(evidence.model),
                "slave": evidence.slave,
                "fits": evidence.fits(),
                "evidence": findings,
            })
        })
        .collect();
    json!({"model": model, "fitting": fitting, "candidates": candidates})
}

//! A scan's [`Report`] as JSON and back, exactly (f64 values round-trip
//! bit for bit): how finished blocks of a long scan are recorded on disk
//! for resuming, and sent between MPI ranks.

use crate::classifier::Verdict;
use crate::scan::{Report, Row, StageSeconds};
use crate::series::{SkipReason, Skipped};
use crate::triggers::Trigger;
use crate::Error;
use serde_json::{json, Value};

const REASONS: [(SkipReason, &str); 5] = [
    (SkipReason::MissingSamples, "missing_samples"),
    (SkipReason::NoDataFlag, "no_data_flag"),
    (SkipReason::GapBetweenFiles, "gap_between_files"),
    (SkipReason::TooShort, "too_short"),
    (SkipReason::SegmentEdges, "segment_edges"),
];

/// `report` as a JSON value.
pub fn report_to_json(report: &Report) -> Value {
    let rows: Vec<Value> = report
        .rows
        .iter()
        .map(|r| {
            let t = &r.trigger;
            json!({
                "time": t.time, "start": t.start, "end": t.end,
                "peak_frequency": t.peak_frequency, "f_start": t.f_start, "f_end": t.f_end,
                "snr": t.snr, "significance": t.significance, "q": t.q,
                "peak_duration": t.peak_duration, "tiles": t.tiles,
                "verdict": r.verdict.as_ref().map(|v| json!({"label": v.label, "probabilities": v.probabilities})),
            })
        })
        .collect();
    let skipped: Vec<Value> = report
        .skipped
        .iter()
        .map(|s| {
            let reason = REASONS.iter().find(|(r, _)| *r == s.reason).map_or("segment_edges", |(_, n)| n);
            json!({"gps_start": s.gps_start, "seconds": s.seconds, "reason": reason})
        })
        .collect();
    let st = &report.stage_seconds;
    json!({
        "ifo": report.ifo,
        "rows": rows,
        "scanned_seconds": report.scanned_seconds,
        "skipped": skipped,
        "tiled_band": [report.tiled_band.0, report.tiled_band.1],
        "stage_seconds": {"psd": st.psd, "whiten": st.whiten, "tiles": st.tiles, "classify": st.classify},
    })
}

/// The report that [`report_to_json`] wrote; `what` names the record in errors.
pub fn report_from_json(v: &Value, what: &str) -> Result<Report, Error> {
    let bad = |field: &str| Error::Data(format!("{what}: field `{field}` is missing or not of the right type"));
    let num = |o: &Value, field: &str| o.get(field).and_then(Value::as_f64).ok_or_else(|| bad(field));
    let list = |o: &Value, field: &str| o.get(field).and_then(Value::as_array).cloned().ok_or_else(|| bad(field));
    let mut rows = Vec::new();
    for r in list(v, "rows")? {
        let trigger = Trigger {
            time: num(&r, "time")?,
            start: num(&r, "start")?,
            end: num(&r, "end")?,
            peak_frequency: num(&r, "peak_frequency")?,
            f_start: num(&r, "f_start")?,
            f_end: num(&r, "f_end")?,
            snr: num(&r, "snr")?,
            significance: num(&r, "significance")?,
            q: num(&r, "q")?,
            peak_duration: num(&r, "peak_duration")?,
            tiles: r.get("tiles").and_then(Value::as_u64).ok_or_else(|| bad("tiles"))? as usize,
        };
        let verdict = match r.get("verdict") {
            None | Some(Value::Null) => None,
            Some(v) => Some(Verdict {
                label: v.get("label").and_then(Value::as_u64).ok_or_else(|| bad("verdict.label"))? as usize,
                probabilities: list(v, "probabilities")?
                    .iter()
                    .map(|p| p.as_f64().ok_or_else(|| bad("verdict.probabilities")))
                    .collect::<Result<_, _>>()?,
            }),
        };
        rows.push(Row { trigger, verdict });
    }
    let mut skipped = Vec::new();
    for s in list(v, "skipped")? {
        let name = s.get("reason").and_then(Value::as_str).ok_or_else(|| bad("skipped.reason"))?;
        let reason = REASONS.iter().find(|(_, n)| *n == name).map(|(r, _)| *r).ok_or_else(|| bad("skipped.reason"))?;
        skipped.push(Skipped { gps_start: num(&s, "gps_start")?, seconds: num(&s, "seconds")?, reason });
    }
    let band = list(v, "tiled_band")?;
    let st = v.get("stage_seconds").ok_or_else(|| bad("stage_seconds"))?;
    Ok(Report {
        ifo: v.get("ifo").and_then(Value::as_str).ok_or_else(|| bad("ifo"))?.to_string(),
        rows,
        scanned_seconds: num(v, "scanned_seconds")?,
        skipped,
        tiled_band: (
            band.first().and_then(Value::as_f64).ok_or_else(|| bad("tiled_band"))?,
            band.get(1).and_then(Value::as_f64).ok_or_else(|| bad("tiled_band"))?,
        ),
        stage_seconds: StageSeconds {
            psd: num(st, "psd")?,
            whiten: num(st, "whiten")?,
            tiles: num(st, "tiles")?,
            classify: num(st, "classify")?,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every field, awkward floats included, comes back bit for bit.
    #[test]
    fn reports_round_trip_exactly() {
        let trigger = Trigger {
            time: 1_126_259_462.422_119_1,
            start: 1_126_259_462.1 + 1e-9,
            end: 1_126_259_463.0 / 3.0,
            peak_frequency: 0.1 + 0.2,
            f_start: 10.0,
            f_end: 2_047.999_999_999_999_8,
            snr: 7.5 + f64::EPSILON * 8.0,
            significance: 6.02,
            q: 5.656_854_249_492_381,
            peak_duration: 1e-300,
            tiles: 17,
        };
        let report = Report {
            ifo: "L1".into(),
            rows: vec![
                Row { trigger: trigger.clone(), verdict: Some(Verdict { label: 2, probabilities: vec![0.1, 0.7, 1.0 / 3.0] }) },
                Row { trigger, verdict: None },
            ],
            scanned_seconds: 1016.0,
            skipped: REASONS.iter().map(|(r, _)| Skipped { gps_start: 1e9 + 0.5, seconds: 4.0, reason: *r }).collect(),
            tiled_band: (10.0, 1_448.154_687_5),
            stage_seconds: StageSeconds { psd: 0.25, whiten: 1.0 / 7.0, tiles: 2.0, classify: 0.0 },
        };
        let text = serde_json::to_string(&report_to_json(&report)).unwrap();
        let back = report_from_json(&serde_json::from_str(&text).unwrap(), "test").unwrap();
        assert_eq!(back, report);
        for (a, b) in back.rows.iter().zip(&report.rows) {
            assert_eq!(a.trigger.time.to_bits(), b.trigger.time.to_bits());
        }
    }

    #[test]
    fn a_damaged_record_names_the_field() {
        let mut v = report_to_json(&Report {
            ifo: "H1".into(),
            rows: Vec::new(),
            scanned_seconds: 1.0,
            skipped: Vec::new(),
            tiled_band: (10.0, 20.0),
            stage_seconds: StageSeconds::default(),
        });
        v["skipped"] = json!([{"gps_start": 1.0, "seconds": 2.0, "reason": "sunspots"}]);
        let e = report_from_json(&v, "block-00003.json").unwrap_err().to_string();
        assert!(e.contains("block-00003.json") && e.contains("skipped.reason"), "{e}");
    }
}

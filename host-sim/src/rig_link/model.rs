//! `rig model`: the rig's own model and calibration from the desktop. A push stages every field
//! in a draft on the rig (`draft begin`, `model …`, `calib …`) and applies it whole (`draft
//! apply`), so that the rig takes all of it or none (a refusal or a failure discards the
//! draft); it is verified by the model line the rig answers, whose fields and hash must be the
//! desktop's bit for bit. A pull reads the active model, calibration and gap back as the TOML
//! `select --config` reads.

use anyhow::{Context, Result, bail, ensure};
use shared::console::{Answer, CalibView, DraftCommand, ModelOf, ModelView, Request, StoreView};
use shared::control::{CalibField, Calibration, ModelSource};
use shared::model::{ModelEdit, ModelField, RigParams, SuspensionKind, params_hash};

use super::RigPort;

/// What a push left on the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pushed {
    /// The model's hash, as the rig reported it (the desktop's).
    pub hash: u32,
    /// The store line after `save`, when asked.
    pub saved: Option<StoreView>,
}

/// Pushes `params` (and `calibration`, when given) to the rig as one change, then `save`s it
/// when `save`.
///
/// # Errors
/// The rig refused a field or the whole (the draft discarded: nothing changed; the message
/// names the field and its range), the model it reports differs from `params`, the link failed
/// (the draft, if any, discarded by the rig at its next `draft begin`; nothing applied).
pub fn push(
    port: &mut RigPort,
    params: &RigParams,
    calibration: Option<&Calibration>,
    save: bool,
) -> Result<Pushed> {
    let draft = model_line(port, &Request::Draft(DraftCommand::Begin))?;
    let staged = stage(port, draft, params, calibration);
    let applied = match staged {
        Ok(()) => model_line(port, &Request::Draft(DraftCommand::Apply)),
        Err(e) => Err(e),
    };
    let view = match applied {
        Ok(v) => v,
        Err(e) => {
            // Nothing applied: the draft goes (a link that failed may not carry this either;
            // the rig's next `draft begin` replaces the draft).
            let _ = port.request(&Request::Draft(DraftCommand::Discard));
            return Err(e.context("the push was not applied: the rig's model is unchanged"));
        }
    };
    ensure!(
        matches!(view.of, ModelOf::Active(_)) && view.params == *params,
        "the rig reports another model than the one pushed (rig_hash {:08x}, pushed {:08x}): {view}",
        params_hash(&view.params),
        params_hash(params)
    );
    let saved = if save {
        match port.request_ok(&Request::Save)? {
            Answer::Store(s) => {
                ensure!(
                    s.hash == Some(params_hash(params)),
                    "the rig's store holds another model after `save`: {s}"
                );
                Some(s)
            }
            a => bail!("unexpected reply to `save`: {a}"),
        }
    } else {
        None
    };
    Ok(Pushed {
        hash: params_hash(params),
        saved,
    })
}

/// The edits that turn the draft `from` into `params`, and the calibration's, sent in order.
fn stage(
    port: &mut RigPort,
    from: ModelView,
    params: &RigParams,
    calibration: Option<&Calibration>,
) -> Result<()> {
    let mut now = from.params;
    // The law and suspension first (each resets its fields to defaults), then every field.
    if now.contact.kind() != params.contact.kind() {
        now = model_line(
            port,
            &Request::EditModel(ModelEdit::Law(params.contact.kind())),
        )?
        .params;
    }
    let kind = SuspensionKind::of(&params.suspension);
    if SuspensionKind::of(&now.suspension) != kind {
        now = model_line(port, &Request::EditModel(ModelEdit::Suspension(kind)))?.params;
    }
    for field in ModelField::ALL {
        let (Some(want), have) = (params.value(field), now.value(field)) else {
            continue;
        };
        if have.map(f64::to_bits) != Some(want.to_bits()) {
            now = model_line(port, &Request::EditModel(ModelEdit::Set(field, want)))?.params;
        }
    }
    if let Some(cal) = calibration {
        for field in CalibField::ALL {
            let v = cal.value(field);
            match port.request_ok(&Request::EditCalib(field, v))? {
                Answer::Calib(c) if c.calibration.value(field).to_bits() == v.to_bits() => {}
                a => bail!("the rig answered `calib {field}` with `{a}`"),
            }
        }
    }
    Ok(())
}

/// The model line the rig answers `request` with.
fn model_line(port: &mut RigPort, request: &Request) -> Result<ModelView> {
    match port.request_ok(request)? {
        Answer::Model(m) => Ok(m),
        a => bail!("unexpected reply to `{request}`: {a}"),
    }
}

/// The rig's active model (and where it came from), calibration and gap.
///
/// # Errors
/// As [`RigPort::request_ok`]; a draft open on the rig.
pub fn pull(port: &mut RigPort) -> Result<(RigParams, ModelSource, Calibration, f32)> {
    let view = model_line(port, &Request::Model)?;
    let ModelOf::Active(source) = view.of else {
        bail!("a draft is open on the rig: `rig send \"draft apply\"` or \"draft discard\" first");
    };
    let calibration = match port.request_ok(&Request::Calib)? {
        Answer::Calib(CalibView {
            draft: false,
            calibration,
        }) => calibration,
        a => bail!("unexpected reply to `calib`: {a}"),
    };
    let gap_mm = port.status()?.gap_mm;
    Ok((view.params, source, calibration, gap_mm))
}

/// The TOML of a pulled model: `[rig]` (every field) and `[calibration]`, which `select
/// --config` and `rig model push --config` read back to the same bits, with `comment` as `#`
/// lines on top.
///
/// # Errors
/// Serialisation failure.
pub fn toml_text(comment: &str, params: &RigParams, calibration: &Calibration) -> Result<String> {
    let mut root = toml::Table::new();
    root.insert(
        "rig".into(),
        toml::Value::try_from(params).context("writing [rig]")?,
    );
    root.insert(
        "calibration".into(),
        toml::Value::try_from(calibration).context("writing [calibration]")?,
    );
    let mut out = String::new();
    for line in comment.lines() {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    out.push_str(&toml::to_string(&root).context("writing the model")?);
    Ok(out)
}

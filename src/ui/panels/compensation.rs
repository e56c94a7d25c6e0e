//! The Compensation panel and the approver's credential dialog.

use eframe::egui;

use super::{Forms, UiCommand, labelled_text, severity_color};
use crate::ui::state::Severity;
use crate::ui::vm::compensation::{CompensationView, FlowView, RequestView};

fn request_details(ui: &mut egui::Ui, request: &RequestView) {
    egui::Grid::new(("request", &request.request_id))
        .num_columns(2)
        .spacing([10.0, 4.0])
        .show(ui, |ui| {
            ui.label("Request");
            ui.monospace(&request.request_id);
            ui.end_row();
            ui.label("Action");
            ui.label(&request.action);
            ui.end_row();
            ui.label("Requested by");
            ui.label(&request.operator);
            ui.end_row();
            ui.label("Changes");
            ui.vertical(|ui| {
                for change in &request.changes {
                    ui.monospace(change);
                }
            });
            ui.end_row();
            ui.label("Why");
            ui.label(&request.why);
            ui.end_row();
            ui.label("Evidence");
            ui.label(&request.evidence);
            ui.end_row();
        });
}

/// Draws the Compensation panel (and, while a request awaits approval, the credential dialog).
pub fn compensation_ui(
    ui: &mut egui::Ui,
    view: &CompensationView,
    forms: &mut Forms,
    commands: &mut Vec<UiCommand>,
) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.horizontal(|ui| {
            ui.heading("Controller values");
            if ui.button("Refresh").clicked() {
                commands.push(UiCommand::Refresh);
            }
        });
        if let Some(note) = &view.controller_note {
            ui.colored_label(severity_color(Severity::Warning), note);
        }
        if !view.proposals.is_empty() {
            ui.label(egui::RichText::new("Proposed from the estimates").strong());
            egui::Grid::new("estimate proposals")
                .striped(true)
                .num_columns(6)
                .spacing([10.0, 4.0])
                .show(ui, |ui| {
                    for header in [
                        "value",
                        "applied now [µm]",
                        "proposed [µm]",
                        "change [µm]",
                        "from",
                        "",
                    ] {
                        ui.label(egui::RichText::new(header).strong());
                    }
                    ui.end_row();
                    for p in &view.proposals {
                        ui.monospace(&p.id);
                        ui.monospace(&p.current_um);
                        ui.label(egui::RichText::new(&p.proposed_um).monospace().strong());
                        ui.monospace(&p.change_um);
                        ui.label(&p.basis);
                        match (&p.blocked, p.in_draft) {
                            (Some(reason), _) => {
                                ui.colored_label(severity_color(Severity::Fault), reason);
                            }
                            (None, true) => {
                                ui.weak("in the proposal");
                            }
                            (None, false) => {
                                if ui.button(format!("Use {}", p.id)).clicked() {
                                    commands.push(UiCommand::UseProposal(p.id.clone()));
                                }
                            }
                        }
                        ui.end_row();
                    }
                });
            ui.weak("A proposal is written only after a request and the approver's credential.");
        }
        if !view.values.is_empty() {
            egui::CollapsingHeader::new(format!("{} values", view.values.len()))
                .default_open(true)
                .show(ui, |ui| {
                    egui::Grid::new("controller values")
                        .striped(true)
                        .num_columns(4)
                        .show(ui, |ui| {
                            for header in ["value", "applied now [µm]", "proposed [µm]", "limits"]
                            {
                                ui.label(egui::RichText::new(header).strong());
                            }
                            ui.end_row();
                            for row in &view.values {
                                ui.monospace(&row.id);
                                ui.monospace(&row.current_um);
                                match &row.proposed_um {
                                    Some(p) => {
                                        ui.label(egui::RichText::new(p).monospace().strong())
                                    }
                                    None => ui.label(""),
                                };
                                ui.weak(&row.limits);
                                ui.end_row();
                            }
                        });
                });
        }
        ui.separator();
        ui.heading("Proposal");
        ui.horizontal_wrapped(|ui| {
            let label = ui.label("Value");
            egui::ComboBox::from_id_salt("change id")
                .selected_text(forms.change_id.clone())
                .show_ui(ui, |ui| {
                    for id in &view.ids {
                        ui.selectable_value(&mut forms.change_id, id.clone(), id);
                    }
                })
                .response
                .labelled_by(label.id);
            labelled_text(ui, "New value [µm]", &mut forms.change_value, 80.0);
            if ui.button("Add change").clicked() {
                commands.push(UiCommand::AddChange);
            }
        });
        for change in &view.draft {
            ui.horizontal(|ui| {
                ui.monospace(change);
                if ui.small_button("remove").clicked() {
                    let id = change.split(' ').next().unwrap_or_default().to_string();
                    commands.push(UiCommand::RemoveChange(id));
                }
            });
        }
        super::form_grid("proposal text", ui, |ui| {
            labelled_text(ui, "Why", &mut forms.why, 420.0);
            ui.end_row();
            labelled_text(ui, "Evidence", &mut forms.evidence, 420.0);
            ui.end_row();
            labelled_text(ui, "Operator", &mut forms.operator, 200.0);
            ui.end_row();
        });
        ui.horizontal(|ui| {
            let enabled = view.request_blocked.is_none();
            if ui
                .add_enabled(enabled, egui::Button::new("Request push"))
                .clicked()
            {
                commands.push(UiCommand::RequestPush);
            }
            if let Some(reason) = &view.request_blocked {
                ui.weak(reason);
            }
        });
        if let Some(notice) = &view.notice {
            ui.colored_label(severity_color(Severity::Fault), notice);
        }
        ui.weak(&view.users_note);
        match &view.flow {
            FlowView::Idle | FlowView::AwaitingApproval { .. } => {}
            FlowView::Writing { request, approver } => {
                ui.separator();
                ui.horizontal(|ui| {
                    ui.spinner();
                    ui.label(format!(
                        "Request {}: checking {approver}'s credential, writing, reading back…",
                        request.request_id
                    ));
                });
            }
            FlowView::Finished(result) => {
                ui.separator();
                ui.heading("Result");
                let severity = if result.verified {
                    Severity::Normal
                } else {
                    Severity::Fault
                };
                ui.colored_label(
                    severity_color(severity),
                    format!(
                        "Request {} ({}): {}",
                        result.request_id, result.action, result.message
                    ),
                );
                egui::Grid::new("push result")
                    .striped(true)
                    .num_columns(4)
                    .show(ui, |ui| {
                        for header in ["value", "before [µm]", "requested [µm]", "read back [µm]"]
                        {
                            ui.label(egui::RichText::new(header).strong());
                        }
                        ui.end_row();
                        for value in &result.values {
                            ui.monospace(&value.id);
                            ui.monospace(crate::ui::vm::number(value.old_um, 1));
                            ui.monospace(format!("{:.1}", value.requested_um));
                            ui.monospace(crate::ui::vm::number(value.read_back_um, 1));
                            ui.end_row();
                        }
                    });
                if ui.button("Close result").clicked() {
                    commands.push(UiCommand::DismissResult);
                }
            }
        }
        ui.separator();
        ui.heading("Audit history");
        if let Some(note) = &view.audit_note {
            ui.colored_label(severity_color(Severity::Fault), note);
        }
        if view.audit.is_empty() {
            ui.weak("No entries yet.");
        }
        egui::Grid::new("audit")
            .striped(true)
            .num_columns(8)
            .spacing([10.0, 4.0])
            .show(ui, |ui| {
                for header in [
                    "#",
                    "time (UTC)",
                    "request",
                    "who",
                    "step",
                    "outcome",
                    "changes",
                    "",
                ] {
                    ui.label(egui::RichText::new(header).strong());
                }
                ui.end_row();
                for row in &view.audit {
                    ui.label(row.index.to_string());
                    ui.monospace(&row.time_utc);
                    ui.monospace(&row.request_id).on_hover_text(&row.action);
                    ui.label(&row.who);
                    ui.label(&row.step);
                    ui.label(&row.outcome).on_hover_text(&row.detail);
                    ui.monospace(&row.changes);
                    if row.can_roll_back {
                        if ui
                            .small_button(format!("Roll back {}", row.request_id))
                            .clicked()
                        {
                            commands.push(UiCommand::Rollback(row.request_id.clone()));
                        }
                    } else {
                        ui.label("");
                    }
                    ui.end_row();
                }
            });
    });
    if let FlowView::AwaitingApproval {
        request,
        approvers,
        refusal,
    } = &view.flow
    {
        egui::Modal::new(egui::Id::unique("approval dialog")).show(ui.ctx(), |ui| {
            ui.set_width(460.0);
            ui.heading("Approve compensation push");
            request_details(ui, request);
            ui.separator();
            if approvers.is_empty() {
                ui.colored_label(
                    severity_color(Severity::Warning),
                    "No approver other than the requester is in the users file.",
                );
            } else {
                ui.weak(format!("Approvers: {}", approvers.join(", ")));
            }
            super::form_grid("credential", ui, |ui| {
                labelled_text(ui, "Approver", &mut forms.approver, 200.0);
                ui.end_row();
                let label = ui.label("Password");
                let response = ui
                    .add(
                        egui::TextEdit::singleline(&mut forms.password)
                            .password(true)
                            .desired_width(200.0),
                    )
                    .labelled_by(label.id);
                if response.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
                    commands.push(UiCommand::SubmitApproval);
                }
                ui.end_row();
            });
            if let Some(reason) = refusal {
                ui.colored_label(
                    severity_color(Severity::Fault),
                    format!("Refused: {reason}"),
                );
            }
            ui.label("Nothing is written until the credential is accepted.");
            ui.horizontal(|ui| {
                if ui.button("Approve and write").clicked() {
                    commands.push(UiCommand::SubmitApproval);
                }
                if ui.button("Cancel request").clicked() {
                    commands.push(UiCommand::CancelRequest);
                }
            });
        });
    }
}

// The job list: one row per job with a live progress bar (one event stream for all jobs).

import { api, follow, getJSON } from "../api.js";
import { clear, h, progressBar } from "../dom.js";
import { ACTIVE, duration, progressLabel, timestamp } from "../format.js";

function row(job, onAction) {
  const p = job.progress;
  const label = progressLabel(job);
  const eta = job.state === "running" ? `ETA ${duration(p.eta_s)}` : "";
  return h("tr", { class: `job state-${job.state}`, dataset: { id: job.id, state: job.state } },
    h("td", {}, h("a", { href: `#/jobs/${job.id}` }, job.name), h("div", { class: "muted small" }, job.id)),
    h("td", {}, h("span", { class: `badge ${job.state}` }, job.state)),
    h("td", { class: "progress-cell" }, progressBar(p.fraction, label),
      h("div", { class: "muted small" }, [eta, p.operation].filter(Boolean).join(" · "))),
    h("td", { class: "small" }, timestamp(job.created_at)),
    h("td", { class: "small message" }, job.message),
    h("td", { class: "actions" },
      h("a", { href: `#/jobs/${job.id}`, class: "button" }, "Open"),
      ACTIVE.has(job.state) ? h("button", { type: "button", class: "danger",
        title: "Stop this job for good (the CLs finished so far are kept)", onclick: () => onAction("cancel", job) },
      "Cancel") : null,
      h("button", { type: "button", class: "danger", onclick: () => onAction("delete", job) }, "Delete")));
}

export function render(root, { go }) {
  const jobs = new Map();
  const tbody = h("tbody", { id: "job-rows" });
  const empty = h("p", { class: "muted", id: "no-jobs" }, "No jobs yet. ", h("a", { href: "#/new" }, "Submit one"), ".");
  const error = h("div", { class: "error", hidden: true });

  const onAction = async (what, job) => {
    error.hidden = true;
    try {
      if (what === "cancel") await api(`/api/jobs/${job.id}/cancel`, { method: "POST" });
      if (what === "delete") {
        if (!confirm(`Delete job ${job.name} and its files?`)) return;
        await api(`/api/jobs/${job.id}`, { method: "DELETE" });
        jobs.delete(job.id);
        draw();
      }
    } catch (err) {
      error.textContent = err.message;
      error.hidden = false;
    }
  };

  const draw = () => {
    clear(tbody);
    const list = [...jobs.values()].sort((a, b) => b.created_at - a.created_at || a.id.localeCompare(b.id));
    for (const j of list) tbody.append(row(j, onAction));
    empty.hidden = list.length > 0;
  };

  root.append(h("h1", {}, "Jobs"), error, empty,
    h("table", { class: "jobs" },
      h("thead", {}, h("tr", {}, ["job", "state", "progress", "submitted", "", ""].map((c) => h("th", {}, c)))),
      tbody));

  getJSON("/api/jobs").then((r) => {
    for (const j of r.jobs) jobs.set(j.id, j);
    draw();
  }).catch((err) => {
    error.textContent = err.message;
    error.hidden = false;
  });
  const stream = follow("/api/events", (event, data) => {
    if (event === "job") jobs.set(data.id, data);
    if (event === "deleted") jobs.delete(data.id);
    draw();
  });
  return () => stream.stop();
}

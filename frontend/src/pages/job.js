// One job: live progress, then the per-operation summary, plots, the 3D view and the files.

import { ApiError, api, blobURL, download, follow, getJSON } from "../api.js";
import { clear, h, progressBar } from "../dom.js";
import { ACTIVE, bytes, duration, number, progressLabel, timestamp } from "../format.js";

const SUMMARY_COLUMNS = [
  ["operation", "operation"], ["cls", "CLs"], ["processed", "done"], ["engaged", "engaged"], ["air", "air"], ["rapid", "rapid"],
  ["failed", "failed"], ["volume_removed_mm3", "removed mm³"], ["max_ae_mm", "max ae mm"],
  ["max_ap_mm", "max ap mm"], ["time_s", "time s"],
];

export function render(root, { params }) {
  const id = params.id;
  const urls = [];
  let view = null;
  let loaded = false;
  const header = h("div", { class: "card", id: "job-header" });
  const results = h("div", { id: "results" });
  const error = h("div", { class: "error", hidden: true });
  root.append(h("p", {}, h("a", { href: "#/jobs" }, "← all jobs")), error, header, results);

  const showHeader = (job) => {
    const p = job.progress;
    clear(header).append(...[
      h("h1", {}, job.name, " ", h("span", { class: `badge ${job.state}`, id: "job-state" }, job.state)),
      progressBar(p.fraction, progressLabel(job)),
      h("p", { class: "muted small" },
        job.state === "running" ? `${p.operation || ""} · ${number(p.rate_cl_s, 3)} CL/s · ETA ${duration(p.eta_s)}` : "",
        ` submitted ${timestamp(job.created_at)}`, job.finished_at ? `, finished ${timestamp(job.finished_at)}` : ""),
      job.message ? h("p", { class: job.state === "failed" ? "error" : "" }, job.message) : null,
      ACTIVE.has(job.state)
        ? h("button", { type: "button", onclick: () => api(`/api/jobs/${id}/cancel`, { method: "POST" }).catch(fail) }, "Cancel")
        : null].filter(Boolean));
  };
  const fail = (err) => {
    error.textContent = err.message;
    error.hidden = false;
  };

  const loadResults = async (job) => {
    if (loaded) return;
    loaded = true;
    clear(results);
    const summary = h("section", { class: "card" }, h("h2", {}, "Summary per operation"));
    const plots = h("section", { class: "card plots" }, h("h2", {}, "Engagement"));
    const viewCard = h("section", { class: "card" }, h("h2", {}, "3D view"));
    const files = h("section", { class: "card" }, h("h2", {}, "Files"));
    results.append(summary, plots, viewCard, files);
    try {
      const s = await getJSON(`/api/jobs/${id}/summary`);
      summary.append(h("table", { class: "summary", id: "summary-table" },
        h("thead", {}, h("tr", {}, SUMMARY_COLUMNS.map(([, t]) => h("th", {}, t)))),
        h("tbody", {}, s.rows.map((r) => h("tr", {}, SUMMARY_COLUMNS.map(([k]) =>
          h("td", { class: k === "operation" ? "" : "num" }, k === "operation" ? r[k] || "–" : number(r[k], 4))))))));
    } catch (err) {
      summary.append(h("p", { class: "muted" }, err instanceof ApiError ? err.message : String(err)));
    }
    for (const kind of ["program", "heatmap"]) {
      const img = h("img", { alt: `${kind} plot`, class: "plot", id: `plot-${kind}` });
      plots.append(img);
      blobURL(`/api/jobs/${id}/plots/${kind}`).then((u) => {
        urls.push(u);
        img.src = u;
      }).catch((err) => img.replaceWith(h("p", { class: "muted" }, `${kind}: ${err.message}`)));
    }
    try {
      const list = await getJSON(`/api/jobs/${id}/files`);
      files.append(h("ul", { class: "files" }, list.files.map((f) => h("li", {},
        h("a", { href: "#", onclick: (e) => {
          e.preventDefault();
          download(f.url, f.name).catch(fail);
        } }, f.name), ` (${bytes(f.size)})`))));
    } catch (err) {
      files.append(h("p", { class: "muted" }, err.message));
    }
    try {
      const { JobView } = await import("../view3d.js");
      view = new JobView(viewCard, id);
      await view.load();
    } catch (err) {
      viewCard.append(h("p", { class: "error" }, `3D view: ${err.message}`));
    }
  };

  let stream = null;
  getJSON(`/api/jobs/${id}`).then((job) => {
    showHeader(job);
    if (!ACTIVE.has(job.state)) {
      loadResults(job);
      return;
    }
    stream = follow(`/api/jobs/${id}/events`, (event, data) => {
      if (event === "status") {
        showHeader(data);
        if (!ACTIVE.has(data.state)) loadResults(data);
      }
      if (event === "end" || event === "deleted") return false;
      return true;
    }, fail);
  }).catch(fail);

  return () => {
    if (stream) stream.stop();
    if (view) view.dispose();
    urls.forEach((u) => URL.revokeObjectURL(u));
  };
}

// One job: live progress (with the plots so far and the 3D view at the latest finished CL while it
// runs), then the per-operation summary, plots, the 3D view and the files.

import { ApiError, api, blobURL, download, follow, getJSON } from "../api.js";
import { clear, h, progressBar } from "../dom.js";
import { ACTIVE, bytes, duration, number, progressLabel, timestamp } from "../format.js";

const SUMMARY_COLUMNS = [
  ["operation", "operation"], ["cls", "CLs"], ["processed", "done"], ["engaged", "engaged"], ["air", "air"], ["rapid", "rapid"],
  ["failed", "failed"], ["volume_removed_mm3", "removed mm³"], ["max_ae_mm", "max ae mm"],
  ["max_ap_mm", "max ap mm"], ["time_s", "time s"],
];

const LIVE_VIEW_MS = 3000;
const LIVE_PLOTS_MS = 10000;

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
        ? h("button", { type: "button", class: "danger", id: "cancel-button",
          title: "Stop this job for good (the CLs finished so far are kept)",
          onclick: () => api(`/api/jobs/${id}/cancel`, { method: "POST" }).catch(fail) }, "Cancel job")
        : null].filter(Boolean));
  };
  const fail = (err) => {
    error.textContent = err.message;
    error.hidden = false;
  };

  const showPlot = (kind, img) => blobURL(`/api/jobs/${id}/plots/${kind}`).then((u) => {
    urls.push(u);
    img.src = u;
  });

  // While the job runs: the plots so far and the 3D view at the latest finished CL, refreshed every
  // LIVE_VIEW_MS (plots every LIVE_PLOTS_MS: each is drawn from the whole results so far).
  let live = null;
  const showLive = async (job) => {
    if (loaded || job.state !== "running" || !job.progress.done || (live && live.busy)) return;
    const now = Date.now();
    if (live && now - live.viewAt < LIVE_VIEW_MS) return;
    if (!live) {
      // the first CLs reach the result tables a little after the progress counts them (the tables
      // are written empty when the run starts): ask for plots and the scene once they hold a CL
      // (a 404 would be an error in the console)
      live = { busy: true, viewAt: now };
      const ready = await getJSON(`/api/jobs/${id}/files`)
        .then((l) => l.files.some((f) => f.name === "cl.parquet") && getJSON(`/api/jobs/${id}/summary`))
        .then((t) => Boolean(t) && t.rows.some((r) => r.processed > 0), () => false);
      live = null;
      if (!ready || loaded) return;
      const plots = h("section", { class: "card plots" }, h("h2", {}, "Engagement so far"));
      const viewCard = h("section", { class: "card" }, h("h2", {}, "3D view (latest finished CL)"));
      const imgs = ["program", "heatmap"].map((kind) => h("img", { alt: `${kind} plot`, class: "plot", id: `plot-${kind}` }));
      plots.append(...imgs);
      clear(results).append(plots, viewCard);
      live = { imgs, viewCard, plotsAt: 0, viewAt: 0, busy: false };
    }
    live.busy = true;
    live.viewAt = now;
    try {
      if (now - live.plotsAt >= LIVE_PLOTS_MS) {
        live.plotsAt = now;
        ["program", "heatmap"].forEach((kind, k) => showPlot(kind, live.imgs[k]).catch(() => {}));
      }
      if (!view) {
        const { JobView } = await import("../view3d.js");
        if (loaded) return;
        view = new JobView(live.viewCard, id);
        await view.load();
      } else {
        await view.refresh();
      }
    } catch (err) {
      if (err instanceof ApiError && err.status === 404) return; // no results yet: next time
      if (view) view.dispose();
      view = null;
      live.viewCard.append(h("p", { class: "error" }, `3D view: ${err.message}`));
    } finally {
      live.busy = false;
    }
  };

  const loadResults = async (job) => {
    if (loaded) return;
    loaded = true;
    if (view) view.dispose();
    view = null;
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
      showPlot(kind, img).catch((err) => img.replaceWith(h("p", { class: "muted" }, `${kind}: ${err.message}`)));
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
    showLive(job);
    stream = follow(`/api/jobs/${id}/events`, (event, data) => {
      if (event === "status") {
        showHeader(data);
        if (!ACTIVE.has(data.state)) loadResults(data);
        else showLive(data);
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

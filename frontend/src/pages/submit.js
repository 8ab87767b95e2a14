// New job: the demo, or uploaded toolpath files with tools, stock and options.

import { api } from "../api.js";
import { h } from "../dom.js";

const TOOL_KINDS = ["flat", "ball", "bullnose", "tapered", "chamfer"];

function toolRow() {
  const row = h("tr", { class: "tool-row" },
    h("td", {}, h("input", { name: "t_number", type: "number", min: "0", step: "1", value: "1", "aria-label": "T number" })),
    h("td", {}, h("select", { name: "t_kind", "aria-label": "tool kind" }, TOOL_KINDS.map((k) => h("option", { value: k }, k)))),
    h("td", {}, h("input", { name: "t_diameter", type: "number", min: "0", step: "any", placeholder: "mm", "aria-label": "diameter" })),
    h("td", {}, h("input", { name: "t_flute", type: "number", min: "0", step: "any", placeholder: "mm", "aria-label": "flute length" })),
    h("td", {}, h("input", { name: "t_corner", type: "number", min: "0", step: "any", placeholder: "mm", "aria-label": "corner radius / taper angle" })),
    h("td", {}, h("button", { type: "button", class: "link", onclick: () => row.remove() }, "remove")));
  return row;
}

function num(form, name) {
  const v = form.elements[name] && form.elements[name].value;
  return v === "" || v === undefined ? null : Number(v);
}

// The partial job the form describes; the service fills in the uploaded file names.
export function jobFromForm(form) {
  const job = {};
  const name = form.elements.name.value.trim();
  if (name) job.name = name;
  const stockKind = form.elements.stock_kind.value;
  if (stockKind === "box") {
    const v = ["x0", "y0", "z0", "x1", "y1", "z1"].map((k) => num(form, k));
    job.stock = { kind: "box", min: v.slice(0, 3), max: v.slice(3) };
  } else if (stockKind === "infer") {
    job.stock = { kind: "infer", margin: num(form, "margin") ?? 2 };
  } // "file": the service takes the uploaded STEP file
  const tools = [];
  for (const row of form.querySelectorAll(".tool-row")) {
    const q = (n) => row.querySelector(`[name=${n}]`).value;
    if (q("t_diameter") === "") continue;
    const kind = q("t_kind");
    const t = { number: Number(q("t_number")), kind, diameter: Number(q("t_diameter")),
      flute_length: Number(q("t_flute") || 3 * Number(q("t_diameter"))) };
    const extra = q("t_corner");
    if (extra !== "") {
      if (kind === "bullnose") t.corner_radius = Number(extra);
      if (kind === "tapered" || kind === "chamfer") t.taper_angle = Number(extra);
    }
    tools.push(t);
  }
  if (tools.length) job.tools = tools;
  const options = { slice_height: num(form, "slice_height") ?? 1 };
  const seg = num(form, "max_segment_length");
  if (seg !== null) options.max_segment_length = seg;
  options.sweep = form.elements.sweep.value;
  job.options = options;
  job.strict = form.elements.strict.checked;
  return job;
}

export function render(root, { go }) {
  const error = h("div", { class: "error", id: "submit-error", hidden: true });
  const showError = (msg) => {
    error.textContent = msg;
    error.hidden = false;
  };

  const demo = h("section", { class: "card" },
    h("h2", {}, "Demo"),
    h("p", {}, "An 80 × 50 × 20 mm aluminium block: face pass, full slot, trochoidal clearing, contour and a ball-end finish (about 750 CLs)."),
    h("button", { id: "demo-button", type: "button", onclick: async (e) => {
      e.target.disabled = true;
      error.hidden = true;
      try {
        const r = await api("/api/jobs", { method: "POST", json: { demo: true } });
        const job = await r.json();
        go(`#/jobs/${job.id}`); // its own page: progress, then the results as they come
      } catch (err) {
        showError(err.message);
      } finally {
        e.target.disabled = false;
      }
    } }, "Run the demo job"));

  const tools = h("tbody", {}, toolRow());
  const boxInputs = h("div", { class: "box-inputs", hidden: true },
    ["x0", "y0", "z0"].map((k) => h("label", {}, `min ${k[0]} `, h("input", { name: k, type: "number", step: "any" }))),
    h("br"),
    ["x1", "y1", "z1"].map((k) => h("label", {}, `max ${k[0]} `, h("input", { name: k, type: "number", step: "any" }))));
  const marginInput = h("label", { class: "margin" }, "margin (mm) ", h("input", { name: "margin", type: "number", step: "any", value: "2" }));
  const stockSelect = h("select", { name: "stock_kind", onchange: () => {
    boxInputs.hidden = stockSelect.value !== "box";
    marginInput.hidden = stockSelect.value !== "infer";
  } },
  h("option", { value: "infer" }, "infer from the toolpath"),
  h("option", { value: "box" }, "box"),
  h("option", { value: "file" }, "uploaded STEP/BREP file"));

  const form = h("form", { id: "upload-form", class: "card" },
    h("h2", {}, "Upload a job"),
    h("fieldset", {}, h("legend", {}, "Files"),
      h("label", {}, "Toolpath files (G-code, APT/CLSF, Fusion JSON) ",
        h("input", { type: "file", name: "toolpath", multiple: true, required: true })),
      h("label", {}, "Tool library (.json, .tools, .tbl; optional) ", h("input", { type: "file", name: "tool_library" })),
      h("label", {}, "Stock solid (.step, .stp, .brep; optional) ", h("input", { type: "file", name: "stock", accept: ".step,.stp,.brep" }))),
    h("fieldset", {}, h("legend", {}, "Job"),
      h("label", {}, "Name ", h("input", { name: "name", placeholder: "job" })),
      h("label", {}, "Stock ", stockSelect), marginInput, boxInputs),
    h("fieldset", {}, h("legend", {}, "Tools (optional when the files or the library define them)"),
      h("table", { class: "tools" },
        h("thead", {}, h("tr", {}, ["T", "kind", "diameter", "flute length", "corner r / taper°", ""].map((c) => h("th", {}, c)))),
        tools),
      h("button", { type: "button", class: "link", onclick: () => tools.append(toolRow()) }, "+ add a tool")),
    h("fieldset", {}, h("legend", {}, "Options"),
      h("label", {}, "Slice height (mm) ", h("input", { name: "slice_height", type: "number", step: "any", min: "0", value: "1" })),
      h("label", {}, "Max segment length (mm, empty: whole moves) ", h("input", { name: "max_segment_length", type: "number", step: "any", min: "0" })),
      h("label", {}, "Sweep ", h("select", { name: "sweep" }, h("option", { value: "exact" }, "exact"), h("option", { value: "sampled" }, "sampled"))),
      h("label", {}, h("input", { name: "strict", type: "checkbox" }), " strict (unknown G-code words are errors)")),
    h("button", { type: "submit", id: "submit-button" }, "Submit"));

  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    error.hidden = true;
    const fd = new FormData();
    for (const f of form.elements.toolpath.files) fd.append("toolpath", f, f.name);
    if (form.elements.tool_library.files[0]) fd.append("tool_library", form.elements.tool_library.files[0]);
    if (stockSelect.value === "file") {
      if (!form.elements.stock.files[0]) return showError("choose the STEP file of the stock");
      fd.append("stock", form.elements.stock.files[0]);
    }
    fd.append("job", JSON.stringify(jobFromForm(form)));
    const button = form.querySelector("#submit-button");
    button.disabled = true;
    try {
      const r = await api("/api/jobs", { method: "POST", body: fd });
      const job = await r.json();
      go(`#/jobs?new=${job.id}`);
    } catch (err) {
      showError(err.message);
    } finally {
      button.disabled = false;
    }
  });

  root.append(h("h1", {}, "New job"), error, demo, form);
  return () => {};
}

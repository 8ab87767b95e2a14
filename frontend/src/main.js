// The FusionCut front end: hash routes #/new, #/jobs, #/jobs/<id>; the API key in localStorage.

import { getJSON, getKey, setKey } from "./api.js";
import { clear, h } from "./dom.js";

const routes = [
  [/^#\/new$/, () => import("./pages/submit.js")],
  [/^#\/jobs$/, () => import("./pages/jobs.js")],
  [/^#\/jobs\/([0-9a-f]+)$/, () => import("./pages/job.js"), ["id"]],
];

const main = document.getElementById("main");
const keyForm = document.getElementById("key-form");
const keyInput = document.getElementById("api-key");
const keyState = document.getElementById("key-state");
let cleanup = () => {};
let current = 0; // the route being shown: an older route() still loading its page must not render

function go(hash) {
  if (location.hash === hash) route();
  else location.hash = hash;
}

async function checkKey() {
  if (!getKey()) {
    keyState.textContent = "enter your API key";
    return false;
  }
  try {
    const info = await getJSON("/api/info");
    keyState.textContent = `connected · FusionCut ${info.version}`;
    keyState.className = "ok";
    return true;
  } catch (err) {
    keyState.textContent = err.message;
    keyState.className = "error-text";
    return false;
  }
}

async function route() {
  const ticket = ++current;
  cleanup();
  cleanup = () => {};
  clear(main);
  const path = (location.hash || "#/jobs").split("?")[0];
  if (!getKey()) {
    main.append(h("div", { class: "card" }, h("h1", {}, "Welcome"),
      h("p", {}, "Enter the API key you were given (top right) to see and submit jobs.")));
    return;
  }
  for (const [re, load, names = []] of routes) {
    const m = re.exec(path);
    if (!m) continue;
    const params = Object.fromEntries(names.map((n, i) => [n, m[i + 1]]));
    const page = await load();
    if (ticket !== current) return;
    clear(main);
    cleanup = page.render(main, { go, params }) || (() => {});
    document.querySelectorAll("nav a").forEach((a) => a.classList.toggle("active", path.startsWith(a.getAttribute("href"))));
    return;
  }
  go("#/jobs");
}

keyInput.value = getKey();
keyForm.addEventListener("submit", async (e) => {
  e.preventDefault();
  setKey(keyInput.value);
  await checkKey();
  route();
});
window.addEventListener("hashchange", route);
checkKey();
route();

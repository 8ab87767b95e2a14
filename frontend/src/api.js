// Talking to the FusionCut API: every request carries the X-API-Key header.

const KEY_STORAGE = "fusioncut.apiKey";

export function getKey() {
  return localStorage.getItem(KEY_STORAGE) || "";
}

export function setKey(key) {
  if (key) localStorage.setItem(KEY_STORAGE, key.trim());
  else localStorage.removeItem(KEY_STORAGE);
}

export class ApiError extends Error {
  constructor(status, detail) {
    super(detail);
    this.status = status;
  }
}

// fetch() with the key; a non-2xx answer throws an ApiError carrying the service's message.
export async function api(path, { method = "GET", json, body, signal } = {}) {
  const headers = { "X-API-Key": getKey() };
  if (json !== undefined) {
    headers["Content-Type"] = "application/json";
    body = JSON.stringify(json);
  }
  let r;
  try {
    r = await fetch(path, { method, headers, body, signal });
  } catch (err) {
    if (err.name === "AbortError") throw err;
    throw new ApiError(0, "the service cannot be reached");
  }
  if (!r.ok) {
    let detail = `${r.status} ${r.statusText}`;
    try {
      const j = await r.json();
      if (j && j.detail) detail = typeof j.detail === "string" ? j.detail : JSON.stringify(j.detail);
    } catch {
      /* not JSON: keep the status line */
    }
    throw new ApiError(r.status, detail);
  }
  return r;
}

export async function getJSON(path, opts) {
  return (await api(path, opts)).json();
}

// An object URL for a file behind the key (img src and download links cannot send headers).
export async function blobURL(path) {
  const r = await api(path);
  return URL.createObjectURL(await r.blob());
}

export async function download(path, name) {
  const url = await blobURL(path);
  const a = document.createElement("a");
  a.href = url;
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

// Follow a server-sent event stream; reconnects after errors until `stop()` is called or the
// handler returns false. Returns {stop}.
export function follow(path, onEvent, onError) {
  const ctrl = new AbortController();
  let stopped = false;
  const stop = () => {
    stopped = true;
    ctrl.abort();
  };
  (async () => {
    const { SSEParser } = await import("./sse.js");
    while (!stopped) {
      try {
        const r = await api(path, { signal: ctrl.signal });
        const reader = r.body.getReader();
        const decoder = new TextDecoder();
        const parser = new SSEParser();
        for (;;) {
          const { value, done } = await reader.read();
          if (done) break;
          for (const ev of parser.feed(decoder.decode(value, { stream: true }))) {
            let data = ev.data;
            try {
              data = JSON.parse(ev.data);
            } catch {
              /* plain text data */
            }
            if (onEvent(ev.event, data) === false) {
              stop();
              return;
            }
          }
        }
      } catch (err) {
        if (stopped || err.name === "AbortError") return;
        if (onError) onError(err);
        if (err.status === 401 || err.status === 404) return;
      }
      if (!stopped) await new Promise((res) => setTimeout(res, 2000));
    }
  })();
  return { stop };
}

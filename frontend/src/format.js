// Formatting of numbers, times and sizes for the pages (pure functions, tested with node --test).

export function percent(fraction) {
  if (!Number.isFinite(fraction)) return "0%";
  const p = Math.max(0, Math.min(1, fraction)) * 100;
  // 99.6% must not read as 100% while the job is still running
  return `${p >= 99.5 && p < 100 ? 99 : Math.round(p)}%`;
}

export function duration(seconds) {
  if (seconds === null || seconds === undefined || !Number.isFinite(seconds) || seconds < 0) return "–";
  const s = Math.round(seconds);
  if (s < 60) return `${s} s`;
  const m = Math.floor(s / 60);
  if (m < 60) return `${m} min ${String(s % 60).padStart(2, "0")} s`;
  return `${Math.floor(m / 60)} h ${String(m % 60).padStart(2, "0")} min`;
}

export function bytes(n) {
  if (!Number.isFinite(n)) return "–";
  const units = ["B", "KiB", "MiB", "GiB"];
  let i = 0;
  while (n >= 1024 && i < units.length - 1) {
    n /= 1024;
    i += 1;
  }
  return i === 0 ? `${n} B` : `${n.toFixed(n < 10 ? 1 : 0)} ${units[i]}`;
}

export function number(v, digits = 3) {
  if (v === null || v === undefined || !Number.isFinite(v)) return "–";
  if (Number.isInteger(v)) return String(v);
  return Number(v.toPrecision(digits)).toString();
}

export function timestamp(unixSeconds) {
  if (!unixSeconds) return "–";
  return new Date(unixSeconds * 1000).toLocaleString();
}

export const ACTIVE = new Set(["queued", "running"]);

// The label of a job's progress bar. A running job can have done every CL and still be writing its
// results (workpiece mesh, plots): it must not read 100 % before the job is done.
export function progressLabel(job) {
  const p = job.progress;
  if (job.state === "running" && p.total && p.done >= p.total) return `${p.done} / ${p.total} CLs · writing results`;
  const fraction = job.state === "done" ? 1 : Math.min(p.fraction, 0.99);
  return `${p.done} / ${p.total} CLs · ${percent(fraction)}`;
}

// The environment options of league.MicroRacerEnv as form fields. Only what differs from the
// defaults goes into env_options, so {} means "the thesis' rules, all options on".

import { element } from "../dom.js";

const SWITCHES = [
  ["obstacles", "Obstacles"],
  ["chicanes", "Chicanes"],
  ["turn_limit", "Turn limit"],
  ["low_speed_termination", "Stop cars that are too slow"],
];
const NUMBERS = [
  ["curves", "Curves", 20, 1],
  ["n_obstacles", "Obstacles per track", 6, 1],
  ["track_width", "Track width", 0.04, 0.005],
  ["max_episode_steps", "Steps before time runs out", 4000, 1],
];

export class EnvOptionsFields {
  constructor(fieldset, prefix) {
    this.inputs = {};
    const checks = element("div", { className: "checks" });
    for (const [key, label] of SWITCHES) {
      const input = element("input", { attrs: { type: "checkbox", id: `${prefix}-${key}`, checked: true } });
      this.inputs[key] = input;
      checks.append(element("label", {}, input, label));
    }
    const numbers = element("div", { className: "row" });
    for (const [key, label, fallback, step] of NUMBERS) {
      const input = element("input", { attrs: { type: "number", id: `${prefix}-${key}`, step, min: 0, placeholder: fallback } });
      this.inputs[key] = input;
      numbers.append(element("div", { className: "field" }, element("label", { text: label, attrs: { for: input.id } }), input));
    }
    fieldset.append(checks, numbers);
  }

  read() {
    const options = {};
    for (const [key] of SWITCHES) if (!this.inputs[key].checked) options[key] = false;
    for (const [key] of NUMBERS) {
      const text = this.inputs[key].value.trim();
      if (text !== "") options[key] = key === "track_width" ? Number(text) : Math.round(Number(text));
    }
    return options;
  }

  show(options = {}) {
    for (const [key] of SWITCHES) this.inputs[key].checked = options[key] !== false;
    for (const [key] of NUMBERS) this.inputs[key].value = options[key] ?? "";
  }
}

export function describeOptions(options = {}) {
  const parts = Object.entries(options).map(([key, value]) => (value === false ? `no ${key.replaceAll("_", " ")}` : `${key.replaceAll("_", " ")} ${value}`));
  return parts.length ? parts.join(", ") : "all options on";
}

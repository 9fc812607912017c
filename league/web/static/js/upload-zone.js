// A drop zone around a file input: drop a file on it, or click / press Enter to pick one.
// The zone is the input's <label>, so the picker and the keyboard work without extra code.

export function dropZone(zone, input, onFile) {
  const choose = (file) => {
    if (file) onFile(file);
  };
  input.addEventListener("change", () => choose(input.files[0]));
  zone.addEventListener("dragover", (event) => {
    event.preventDefault();
    event.dataTransfer.dropEffect = "copy";
    zone.classList.add("dragging");
  });
  zone.addEventListener("dragleave", () => zone.classList.remove("dragging"));
  zone.addEventListener("drop", (event) => {
    event.preventDefault();
    zone.classList.remove("dragging");
    choose(event.dataTransfer.files[0]);
  });
}

// The files of a sequence folder the user gave the page, as [{ path, file }] with `path`
// the folder's name joined with the path inside it ("my_scan/rgb/0.png", as the command
// line would name it from the folder's parent): from the folder picker (<input
// webkitdirectory>, whose files carry webkitRelativePath) or from a folder dropped on the
// page (DataTransferItem.webkitGetAsEntry, walked here). Only the File objects are
// collected; their bytes are read later, one file when the run needs it.

// Files of a picked folder; an error when nothing was picked.
export function filesOfInput(fileList) {
  const files = [...fileList].map((file) => ({ path: file.webkitRelativePath || file.name, file }));
  if (!files.length) throw new Error("the picked folder holds no files");
  return files;
}

// Every file under a directory entry, with its path from the entry's parent.
async function walk(entry, prefix, out) {
  const path = prefix ? `${prefix}/${entry.name}` : entry.name;
  if (entry.isFile) {
    out.push({ path, file: await new Promise((ok, no) => entry.file(ok, no)) });
    return;
  }
  const reader = entry.createReader();
  // readEntries returns at most about a hundred entries per call: call until empty.
  for (;;) {
    const batch = await new Promise((ok, no) => reader.readEntries(ok, no));
    if (!batch.length) break;
    for (const child of batch) await walk(child, path, out);
  }
}

// Files of one dropped folder; an error for files, several items or a browser without
// directory entries.
export async function filesOfDrop(dataTransfer) {
  const entries = [...dataTransfer.items]
    .filter((i) => i.kind === "file")
    .map((i) => i.webkitGetAsEntry?.())
    .filter(Boolean);
  if (entries.length !== 1 || !entries[0].isDirectory) {
    throw new Error(
      `drop one sequence folder (the folder itself, not its files); got ${entries.length} ` +
        `item(s)${entries.length === 1 ? ", a file" : ""}`,
    );
  }
  const out = [];
  await walk(entries[0], "", out);
  if (!out.length) throw new Error(`the dropped folder ${entries[0].name} holds no files`);
  return out;
}

// Asks the simulated PLC what a TwinCAT client asks, with ads-client (npm), and prints one JSON
// object of what came back. Usage: node probe.js IP NET_ID. Used by tests/test_ads_fidelity.py.
// It connects as ads-client does by default (connect.js: the system service on port 10000 first).
const { connected, connection } = require("./connect");

const [ip, netId] = process.argv.slice(2);
const AXIS = "GVL_Axiscal.astAxes[1]";
const COMP = "GVL_Axiscal.astComp[1]";

function failure(err) {
  // where the error came: "ams" (the AMS header) or "ads" (the reply's result field)
  const said = [err.message, ...(err.trace || [])].join("\n");
  const where = /AMS error/.test(said) ? "ams" : /ADS error/.test(said) ? "ads" : "other";
  return { error: err.adsError ? err.adsError.errorCode : null, where, message: err.message };
}

async function attempt(action) {
  try {
    return { value: await action() };
  } catch (err) {
    return failure(err);
  }
}

function items(type) {
  // an array member is reported as its element type with arrayInfos (start index, length)
  return type.subItems.map((s) => ({
    name: s.name, type: s.type, offset: s.offset, size: s.size,
    arrayInfos: s.arrayInfos.map((a) => [a.startIndex, a.length]),
  }));
}

async function main() {
  const client = await connected(ip, netId);
  const out = { connection: connection(client) };
  out.deviceInfo = await attempt(() => client.readDeviceInfo());
  out.state = await attempt(() => client.readState());
  out.symbols = {};
  for (const path of [`${AXIS}.stControl`, `${AXIS}.stStatus`, AXIS, COMP, "GVL_Axiscal.astAxes",
                      `${AXIS}.stStatus.fActPosition`, `${COMP}.afForward`]) {
    out.symbols[path] = await attempt(async () => {
      const s = await client.getSymbol(path);
      return { name: s.name, type: s.type, indexGroup: s.indexGroup, indexOffset: s.indexOffset, size: s.size };
    });
  }
  out.types = {};
  for (const name of ["ST_AxiscalControl", "ST_AxiscalStatus", "ST_AxiscalAxis", "ST_AxiscalComp"]) {
    out.types[name] = await attempt(async () => {
      const t = await client.getDataType(name);
      return { size: t.size, items: items(t) };
    });
  }
  out.status = await attempt(() => client.readValue(`${AXIS}.stStatus`).then((r) => r.value));
  out.comp = await attempt(() => client.readValue(COMP).then((r) => {
    const v = r.value;
    return { ...v, afForward: v.afForward.slice(0, 3), afReverse: v.afReverse.slice(0, 3) };
  }));
  out.writeValue = await attempt(() => client.writeValue(`${AXIS}.stControl.fVelocity`, 12.5).then(() => true));
  const handle = await client.createVariableHandle(`${AXIS}.stControl.eCommand`);
  out.wrongSizeWrite = await attempt(() => client.writeRawByHandle(handle, Buffer.alloc(8, 7)).then(() => true));
  out.afterWrongSize = await attempt(() => client.readValue(`${AXIS}.stControl.eCommand`).then((r) => r.value));
  out.rightSizeWrite = await attempt(() => client.writeRawByHandle(handle, Buffer.from([3, 0])).then(() => true));
  await client.deleteVariableHandle(handle);
  out.unknownSymbol = await attempt(() => client.getSymbol("MAIN.bNoSuchSymbol"));
  out.notification = await attempt(async () => {
    // the first sample is the value when subscribing; it comes without waiting for the PLC to scan
    let first;
    const arrived = new Promise((resolve) => { first = resolve; });
    const s = await client.subscribeValue(`${AXIS}.stStatus.fActPosition`, (data) => first(data.value), 100);
    const value = await Promise.race([arrived, new Promise((resolve) => setTimeout(resolve, 2000, "none"))]);
    await s.unsubscribe();
    return { handle: s.notificationHandle, first: value };
  });
  out.refusedNotification = await attempt(() => client.subscribeRaw(0x1234, 0, 4, () => {}, 100));
  out.writeControl = await attempt(() => client.writeControl(6));
  out.wrongPort = await attempt(() => client.readDeviceInfo({ adsPort: 852 }));
  out.wrongNetId = await attempt(() => client.readDeviceInfo({ amsNetId: "10.1.2.3.1.1" }));
  out.afterAll = await attempt(() => client.readValue(`${AXIS}.stControl`).then((r) => r.value));
  await client.disconnect();
  process.stdout.write(JSON.stringify(out, null, 1) + "\n");
}

main().catch((err) => {
  process.stderr.write(`probe failed: ${err.message}\n`);
  process.exit(1);
});

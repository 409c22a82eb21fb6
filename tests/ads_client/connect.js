// ads-client's default connect to the simulated PLC: no rawClient, no allowHalfOpen, so it asks
// TwinCAT's system service (AMS port 10000) for the system state, polls it every second, and
// watches the runtime's state (0xF100) and symbol version (0xF008) by device notifications, as
// against a real PLC. The local AMS Net ID and port are given because this machine has no ADS
// router of its own (ads-client's "connect from any Node.js system" setup).
const { Client } = require("ads-client");

async function connected(ip, netId) {
  const client = new Client({
    targetAmsNetId: netId, targetAdsPort: 851, routerAddress: ip, routerTcpPort: 48898,
    localAmsNetId: "127.0.0.1.1.7", localAdsPort: 32750, timeoutDelay: 2000, hideConsoleWarnings: true,
  });
  client.clientErrors = [];
  client.on("client-error", (err) => client.clientErrors.push(err.message));
  await client.connect();
  return client;
}

function connection(client) {
  // what the default connect learnt: the system service's state, the runtime's state and symbol
  // version (both from their first notification), and the settings that would have skipped them
  const { tcSystemState, plcRuntimeState, plcSymbolVersion } = client.metaData;
  const { rawClient, allowHalfOpen } = client.settings;
  return { tcSystemState: { ...tcSystemState, reserved: undefined }, plcRuntimeState, plcSymbolVersion,
           rawClient, allowHalfOpen };
}

module.exports = { connected, connection };

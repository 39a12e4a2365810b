// sdram_tb: replays an SDRAM command trace into sdram_checker (and the sdr_sdram device).
//
// Plusargs: +trace=FILE (required): $readmemh words, one command a line,
//   [63:32] cycle (rising edge number, increasing), [31:28] {cs_n, ras_n, cas_n, we_n},
//   [27:26] ba, [12:0] a; the last line has cycle ffffffff.  Cycles not listed are NOP.
// +mem=FILE: load the device's words ($readmemh, sdr_sdram's address order);
// +dump=FILE: write each read beat the controller would sample, "edge hexword" a line.
// At the end (CL + BL + 2 clocks after the last command) one line:
//   SDRAM_COUNTS violations=.. activates=.. reads=.. writes=.. precharges=..
//   auto_precharges=.. refreshes=.. cycles=.. mode_errors=..
`timescale 1ns / 1ps

module sdram_tb;
  parameter integer CL = 2;
  parameter integer BL = 8;
  parameter integer T_RCD = 2;
  parameter integer T_RP = 2;
  parameter integer T_RAS = 5;
  parameter integer T_RAS_MAX = 15000;
  parameter integer T_RC = 8;
  parameter integer T_RRD = 2;
  parameter integer T_WR = 2;
  parameter integer T_RFC = 9;
  parameter integer T_REFI = 976;
  parameter integer T_MRD = 2;
  parameter integer STRICT = 0;
  parameter integer ROWS = 256;
  parameter integer DEPTH = 1 << 20;

  reg clk = 0;
  reg cke = 1, cs_n = 1, ras_n = 1, cas_n = 1, we_n = 1;
  reg [1:0] ba = 0;
  reg [12:0] a = 0;
  reg [63:0] tr[0:DEPTH-1];
  reg [8*256:1] tfile, mfile, dfile;
  integer i = 0, fd = 0, tail = -1;
  wire [15:0] dq_in;
  wire dq_valid;
  wire [31:0] violations, activates, reads, writes, precharges, auto_precharges, refreshes;
  wire [31:0] cycle, mode_errors, refresh_count;
  wire ready;

  sdr_sdram #(
      .CL(CL), .BL(BL), .T_RCD(T_RCD), .T_RP(T_RP), .T_RAS(T_RAS), .T_RC(T_RC),
      .T_RRD(T_RRD), .T_WR(T_WR), .T_RFC(T_RFC), .T_REFI(T_REFI), .ROWS(ROWS)
  ) dev (
      .clk(clk), .cke(cke), .cs_n(cs_n), .ras_n(ras_n), .cas_n(cas_n), .we_n(we_n),
      .ba(ba), .a(a), .dqm(2'b00), .dq_out(16'h0000), .dq_oe(1'b0), .dq_in(dq_in),
      .dq_valid(dq_valid), .mode_errors(mode_errors), .refresh_count(refresh_count)
  );

  sdram_checker #(
      .CL(CL), .BL(BL), .T_RCD(T_RCD), .T_RP(T_RP), .T_RAS(T_RAS), .T_RAS_MAX(T_RAS_MAX),
      .T_RC(T_RC), .T_RRD(T_RRD), .T_WR(T_WR), .T_RFC(T_RFC), .T_REFI(T_REFI),
      .T_MRD(T_MRD), .STRICT(STRICT)
  ) chk (
      .clk(clk), .cke(cke), .cs_n(cs_n), .ras_n(ras_n), .cas_n(cas_n), .we_n(we_n),
      .ba(ba), .a(a), .violations(violations), .activates(activates), .reads(reads),
      .writes(writes), .precharges(precharges), .auto_precharges(auto_precharges),
      .refreshes(refreshes), .cycle(cycle), .ready(ready)
  );

  // Drive the command of rising edge `cycle` (the next one) from the trace.
  task drive;
    begin
      if (tr[i][63:32] == cycle) begin
        {cs_n, ras_n, cas_n, we_n} = tr[i][31:28];
        ba = tr[i][27:26];
        a = tr[i][12:0];
        i = i + 1;
      end else begin
        {cs_n, ras_n, cas_n, we_n} = 4'b0111;
        if (tr[i][63:32] == 32'hffffffff && tail < 0) tail = CL + BL + 2;
      end
    end
  endtask

  initial begin
    if (!$value$plusargs("trace=%s", tfile)) begin
      $display("sdram_tb: +trace=FILE is required");
      $finish;
    end
    $readmemh(tfile, tr);
    if ($value$plusargs("mem=%s", mfile)) dev.load_memh(mfile);
    if ($value$plusargs("dump=%s", dfile)) fd = $fopen(dfile, "w");
    #1 drive();
  end

  always #5 clk = ~clk;

  always @(posedge clk) if (fd != 0 && dq_valid) $fwrite(fd, "%0d %h\n", cycle, dq_in);

  always @(negedge clk) begin
    if (tail == 0) begin
      $display(
          "SDRAM_COUNTS violations=%0d activates=%0d reads=%0d writes=%0d precharges=%0d auto_precharges=%0d refreshes=%0d cycles=%0d mode_errors=%0d",
          violations, activates, reads, writes, precharges, auto_precharges, refreshes,
          cycle, mode_errors);
      if (fd != 0) $fclose(fd);
      $finish;
    end
    if (tail > 0) tail = tail - 1;
    drive();
  end
endmodule

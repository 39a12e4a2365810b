// sdr_sdram: a behavioural SDR SDRAM device (one memory module), pins as in sdram_pins.md.
//
// Ref: Micron 256Mb SDR SDRAM (MT48LC16M16A2, 4 banks x 8192 rows x 512 columns x 16)
//      datasheet: command truth table, mode register (burst length, sequential burst
//      order, CAS latency), READ/WRITE bursts, auto precharge, AUTO REFRESH.
//
// Plain Verilog-2005; runs on Icarus and Verilator.  The device does what the commands
// say; whether they were legal is sdram_checker's job (attach both to the same pins).
// Storage: one word array mem[(bank * ROWS + row) * COLS + column].  The volume image is
// loaded with $readmemh from the MEMFILE parameter at time 0, or later by calling the
// task load_memh(file) (one hex word a line, in that address order).
// Reads: READ sampled at edge T puts beat i of the burst on dq_in from edge T + CL - 1 + i,
// so the controller samples it at edge T + CL + i (CAS latency CL); dq_valid marks the
// beats (an extra output for testbenches).  Bursts follow the mode register's burst length
// in sequential order, wrapping inside the BL-aligned block of columns; a READ or WRITE
// with a[10] = 1 auto-precharges the bank.  Writes take dq_out on the WRITE edge and the
// next BL - 1 edges, masked per byte by dqm.  The mode register must hold the CL and BL
// the device is configured for (CL, BL parameters), else an error line is printed and
// mode_errors counts it.
`timescale 1ns / 1ps

module sdr_sdram #(
    parameter integer CL = 2,
    parameter integer BL = 8,
    parameter integer T_RCD = 2,
    parameter integer T_RP = 2,
    parameter integer T_RAS = 5,
    parameter integer T_RC = 8,
    parameter integer T_RRD = 2,
    parameter integer T_WR = 2,
    parameter integer T_RFC = 9,
    parameter integer T_REFI = 976,
    parameter integer BANKS = 4,
    parameter integer ROWS = 8192,
    parameter integer COLS = 512,
    parameter MEMFILE = ""
) (
    input wire clk,
    input wire cke,
    input wire cs_n,
    input wire ras_n,
    input wire cas_n,
    input wire we_n,
    input wire [1:0] ba,
    input wire [12:0] a,
    input wire [1:0] dqm,
    input wire [15:0] dq_out,
    input wire dq_oe,
    output reg [15:0] dq_in,
    output reg dq_valid,
    output reg [31:0] mode_errors,
    output reg [31:0] refresh_count
);
  localparam integer WORDS = BANKS * ROWS * COLS;
  localparam integer COL_BITS = $clog2(COLS);
  localparam [3:0] C_LMR = 4'b0000, C_REF = 4'b0001, C_PRE = 4'b0010, C_ACT = 4'b0011;
  localparam [3:0] C_WR = 4'b0100, C_RD = 4'b0101;

  reg [15:0] mem[0:WORDS-1];
  reg open[0:BANKS-1];
  reg [12:0] open_row[0:BANKS-1];
  reg [12:0] mode;
  integer burst;  // burst length from the mode register
  integer cas;  // CAS latency from the mode register
  // Beat generator: the burst being read or written, the beat it is at.
  integer rd_base, rd_left, rd_beat, wr_base, wr_left, wr_beat;
  // Read delay line: address of the beat emitted k + 1 edges ago (valid bit, address).
  reg d_v[0:7];
  integer d_a[0:7];
  reg [3:0] cmd;
  reg emit_v;
  integer emit_a, b, k, word;

  task load_memh;
    input [8*256:1] file;
    begin
      $readmemh(file, mem);
    end
  endtask

  initial begin
    for (b = 0; b < BANKS; b = b + 1) begin
      open[b] = 0;
      open_row[b] = 0;
    end
    for (k = 0; k < 8; k = k + 1) begin
      d_v[k] = 0;
      d_a[k] = 0;
    end
    mode = 0;
    burst = BL;
    cas = CL;
    rd_left = 0;
    wr_left = 0;
    rd_base = 0;
    wr_base = 0;
    rd_beat = 0;
    wr_beat = 0;
    dq_in = 0;
    dq_valid = 0;
    mode_errors = 0;
    refresh_count = 0;
    if (MEMFILE != "") $readmemh(MEMFILE, mem);
  end

  // Word address of beat i of a burst starting at column address base (bank, row, col).
  function integer beat_addr;
    input integer base, i, len;
    integer col;
    begin
      col = base % COLS;
      col = (col & ~(len - 1)) | ((col + i) & (len - 1));
      beat_addr = (base - base % COLS) + col;
    end
  endfunction

  always @(posedge clk) begin
    cmd = (!cke || cs_n) ? 4'b0111 : {1'b0, ras_n, cas_n, we_n};
    emit_v = 0;
    emit_a = 0;
    case (cmd)
      C_ACT: begin
        if (a >= ROWS) $display("sdr_sdram: ACTIVATE of row %0d beyond ROWS %0d", a, ROWS);
        open[ba] = 1;
        open_row[ba] = a;
      end
      C_PRE: begin
        if (a[10]) for (b = 0; b < BANKS; b = b + 1) open[b] = 0;
        else open[ba] = 0;
      end
      C_RD, C_WR: begin
        if (!open[ba]) $display("sdr_sdram: %0s of closed bank %0d", cmd == C_RD ? "READ" : "WRITE", ba);
        word = (ba * ROWS + open_row[ba]) * COLS + a[COL_BITS-1:0];
        if (cmd == C_RD) begin
          rd_base = word;
          rd_beat = 0;
          rd_left = burst;
          wr_left = 0;  // a READ ends a write burst
        end else begin
          wr_base = word;
          wr_beat = 0;
          wr_left = burst;
          rd_left = 0;  // a WRITE ends a read burst
        end
        if (a[10]) open[ba] = 0;
      end
      C_REF: refresh_count = refresh_count + 1;
      C_LMR: begin
        mode = a;
        burst = 1 << a[2:0];
        cas = a[6:4];
        if (a[2:0] > 3 || a[3] || a[9] || a[8:7] != 0 || burst != BL || cas != CL) begin
          mode_errors = mode_errors + 1;
          $display("sdr_sdram: mode register %h is not burst %0d sequential CL %0d", a, BL, CL);
        end
      end
      default: ;
    endcase
    if (rd_left > 0) begin
      emit_v = 1;
      emit_a = beat_addr(rd_base, rd_beat, burst);
      rd_beat = rd_beat + 1;
      rd_left = rd_left - 1;
    end
    if (wr_left > 0) begin
      word = beat_addr(wr_base, wr_beat, burst);
      if (!dqm[0]) mem[word][7:0] <= dq_out[7:0];
      if (!dqm[1]) mem[word][15:8] <= dq_out[15:8];
      wr_beat = wr_beat + 1;
      wr_left = wr_left - 1;
    end
    // Beat emitted at edge T drives dq_in from edge T + cas - 1.
    if (cas <= 1) begin
      dq_valid <= emit_v;
      dq_in <= emit_v ? mem[emit_a] : 16'h0000;
    end else begin
      dq_valid <= d_v[cas-2];
      dq_in <= d_v[cas-2] ? mem[d_a[cas-2]] : 16'h0000;
    end
    for (k = 7; k > 0; k = k - 1) begin
      d_v[k] <= d_v[k-1];
      d_a[k] <= d_a[k-1];
    end
    d_v[0] <= emit_v;
    d_a[0] <= emit_a;
  end
endmodule

"""Parameters and O-word control flow of the G-code interpreter (RS274NGC as LinuxCNC reads it).

:class:`FlowMixin` gives :class:`csgnb.apps.gcode._Interpreter` its parameters -- numbered ``#1``..``#5602``
(``#1``..``#30`` local to a call, reading an unset one gives 0; the system parameters ``#5161``.. are
computed from the interpreter's state and read-only), named ``#<name>`` (local to the call) and
``#<_name>`` (global; reading an unset one is an error) -- and its O-words: ``sub``/``endsub``/``return``
(with a value in ``#<_value>``), ``call`` with ``[ ]`` arguments into ``#1``..``#30``, ``if``/``elseif``/
``else``/``endif``, ``while``/``endwhile``, ``do``/``while``, ``repeat``/``endrepeat``, ``break``,
``continue``. The structure is checked for the whole file before the program runs (every block
closed by its own name), and loop passes are bounded.
"""

from __future__ import annotations

from csgnb.apps.gcode_expr import Block, GCodeError, evaluate

__all__ = ["MAX_CALL_DEPTH", "MAX_LOOP_PASSES", "FlowMixin"]


def _has_m99(b: Block) -> bool:
    """Whether the line holds the word M99 (as a literal: a Fanuc subroutine's end is written, not computed)."""
    return any(letter == "M" and text.upper().replace(" ", "").lstrip("M").lstrip("0") in ("99", "99.", "99.0")
               for letter, _, text in b.words)

MAX_LOOP_PASSES = 1_000_000
"""Default bound on the loop passes (while, do, repeat) of one program."""

MAX_CALL_DEPTH = 64
"""Deepest nesting of O-word subroutine calls."""


class _Frame:
    __slots__ = ("autorestore", "locals", "name", "numbered", "return_pc")

    def __init__(self, return_pc, numbered, name):
        self.return_pc, self.numbered, self.name, self.locals = return_pc, numbered, name, {}
        self.autorestore = None  # the caller's modal state, when the sub saved it with M73



class FlowMixin:
    """Parameters (the ``env`` of :func:`csgnb.apps.gcode_expr.evaluate`) and O-word control flow."""

    # -- parameters (the env of evaluate) -------------------------------------------------------------------
    def _locals(self) -> dict:
        return self.frames[-1].locals if self.frames else self.main_locals

    def _computed(self, index: int):
        f = self.factor
        if 5161 <= index <= 5163:
            return self.g28[index - 5161] / f
        if 5181 <= index <= 5183:
            return self.g30[index - 5181] / f
        if index == 5210:
            return 1.0 if self.g92_on else 0.0
        if 5211 <= index <= 5213:
            return self.g92[index - 5211] / f
        if index == 5220:
            return float(self.cs)
        if 5221 <= index <= 5400 and (index - 5221) % 20 < 3:
            return self.g5x[(index - 5221) // 20 + 1][(index - 5221) % 20] / f
        if index == 5400:
            return float(self.loaded or 0)
        if 5401 <= index <= 5403:
            return self.tlo[index - 5401] / f
        if 5420 <= index <= 5422:
            return self._program_position()[index - 5420] / f
        return None

    def read(self, value: float, line: int) -> float:
        index = self._index(value, line)
        c = self._computed(index)
        if c is not None:
            return float(c)
        if index >= 5000:
            raise GCodeError(line, f"#{index} is a system parameter this simulator does not track (probe results, "
                             "tool diameter, I/O results, ...): the program's value would be a guess", f"#{index}")
        return self.numbered.get(index, 0.0)

    def _index(self, value: float, line: int) -> int:
        index = round(value)
        if abs(value - index) > 1e-4 or not 1 <= index <= 5602:
            raise GCodeError(line, f"parameter #{value:g} does not exist: numbered parameters are integers 1..5602",
                             f"#{value:g}")
        return index

    def _named_computed(self, name: str):
        p = self._program_position()
        table = {"_x": p[0] / self.factor, "_y": p[1] / self.factor, "_z": p[2] / self.factor,
                 "_metric": float(self.factor == 1.0), "_imperial": float(self.factor != 1.0),
                 "_absolute": float(self.absolute), "_incremental": float(not self.absolute),
                 "_current_tool": float(self.loaded or 0), "_selected_tool": float(self.selected or 0)}
        return table.get(name)

    def read_named(self, name: str, line: int) -> float:
        store = self.globals if name.startswith("_") else self._locals()
        if name in store:
            return store[name]
        c = self._named_computed(name)
        if c is not None:
            return c
        raise GCodeError(line, f"the parameter #<{name}> is read before any value is assigned to it (assign it "
                         "first, or test it with EXISTS[#<name>])", f"#<{name}>")

    def exists(self, name: str) -> bool:
        store = self.globals if name.startswith("_") else self._locals()
        return name in store or self._named_computed(name) is not None

    def _assign(self, ref, value: float, line: int, text: str) -> None:
        if isinstance(ref, str):
            (self.globals if ref.startswith("_") else self._locals())[ref] = value
            return
        index = self._index(ref, line)
        if self._computed(index) is not None or 5000 <= index <= 5602:
            raise GCodeError(line, f"#{index} is a system parameter this simulator keeps itself; set offsets with "
                             "G10 / G92 / G28.1 instead", text)
        self.numbered[index] = value

    # -- O-word structure ----------------------------------------------------------------------------------
    def _structure(self) -> None:
        self.match, self.chain, self.loop_of, self.subs = {}, {}, {}, {}
        self.tail = set()  # 'while' lines that end a do-loop
        stack: list[tuple[str, str, int]] = []
        for idx, b in enumerate(self.blocks):
            if b.oword is None:
                continue
            name, kw, _ = b.oword
            top = stack[-1] if stack else None

            def closes(opener: str, top=top, name=name, kw=kw, b=b):
                if top is None or top[0] != name or top[1] != opener:
                    open_text = (f"the innermost open block is o{top[0]} {top[1]} at line {self.blocks[top[2]].line}"
                                 if top else "no block is open")
                    raise GCodeError(b.line, f"o{name} {kw} closes no o{name} {opener} ({open_text})", f"o{name}")
                return top[2]

            if kw == "while" and top is not None and top[:2] == (name, "do"):
                self.match[top[2]], self.match[idx] = idx, top[2]
                self.tail.add(idx)
                stack.pop()
            elif kw in ("sub", "if", "while", "do", "repeat"):
                if kw == "sub" and stack:
                    raise GCodeError(b.line, f"o{name} sub is defined inside o{top[0]} {top[1]} (line "
                                     f"{self.blocks[top[2]].line}); define subroutines at the top level", f"o{name}")
                stack.append((name, kw, idx))
                if kw == "if":
                    self.chain[idx] = []
            elif kw in ("elseif", "else"):
                j = closes("if")
                self.chain[j].append(idx)
                self.match[idx] = j
            elif kw in ("endif", "endwhile", "endrepeat", "endsub"):
                j = closes({"endif": "if", "endwhile": "while", "endrepeat": "repeat", "endsub": "sub"}[kw])
                stack.pop()
                self.match[j], self.match[idx] = idx, j
                if kw == "endif":
                    self.chain[j].append(idx)
                if kw == "endsub":
                    if name in self.subs:
                        raise GCodeError(b.line, f"o{name} sub is defined twice (first at line "
                                         f"{self.blocks[self.subs[name][0]].line})", f"o{name}")
                    self.subs[name] = (j, idx)
            elif kw in ("break", "continue"):
                loop = next((e for e in reversed(stack) if e[0] == name and e[1] in ("while", "do", "repeat")), None)
                if loop is None:
                    raise GCodeError(b.line, f"o{name} {kw} is not inside an o{name} while / do / repeat loop",
                                     f"o{name}")
                self.loop_of[idx] = loop[2]
            elif kw == "return":  # LinuxCNC returns from the enclosing sub whatever the label (e.g. an if's)
                if not any(e[1] == "sub" for e in stack):
                    raise GCodeError(b.line, f"o{name} return is not inside a sub", f"o{name}")
        if stack:
            name, kw, idx = stack[-1]
            raise GCodeError(self.blocks[idx].line, f"o{name} {kw} is never closed", f"o{name}")
        self._fanuc_structure()

    def _fanuc_structure(self) -> None:
        """Fanuc-style subroutines (LinuxCNC's M98/M99): a bare ``O<n>`` line followed, before the next bare O line,
        by a line with ``M99`` opens the body of subroutine n, which ``M98 P<n> [L<count>]`` runs; read in order,
        the definition is skipped. A bare O line without its M99 is a program number."""
        self.fanuc_subs: dict[int, tuple[int, int]] = {}
        self.fanuc_frames: list[list[int]] = []  # [return block, sub's O block, calls left]
        self.fanuc_pending = None
        bare = [i for i, b in enumerate(self.blocks) if b.oword is not None and b.oword[1] == "program"]
        for k, start in enumerate(bare):
            stop = bare[k + 1] if k + 1 < len(bare) else len(self.blocks)
            end = next((i for i in range(start + 1, stop) if _has_m99(self.blocks[i])), None)
            if end is not None:
                n = int(self.blocks[start].oword[0])
                if n in self.fanuc_subs:
                    raise GCodeError(self.blocks[start].line, f"O{n} (a subroutine ended by M99) is defined twice "
                                     f"(first at line {self.blocks[self.fanuc_subs[n][0]].line})", f"O{n}")
                self.fanuc_subs[n] = (start, end)
        self.fanuc_ends = {end: start for start, end in self.fanuc_subs.values()}

    def _fanuc_jump(self, pc: int, b: Block) -> int:
        """The next block after a line with M98 (call) or M99 (return)."""
        kind = self.fanuc_pending
        self.fanuc_pending = None
        if kind[0] == "call":
            _, n, count = kind
            if count == 0:
                return pc + 1
            if len(self.fanuc_frames) + len(self.frames) >= MAX_CALL_DEPTH:
                raise GCodeError(b.line, f"M98 P{n} nests deeper than {MAX_CALL_DEPTH} calls", "M98")
            start = self.fanuc_subs[n][0]
            self.fanuc_frames.append([pc + 1, start, count])
            return start + 1
        if not self.fanuc_frames:
            raise GCodeError(b.line, "M99 outside an M98 call: a Fanuc control would run the program again forever; "
                             "end the program with M2 or M30", "M99")
        frame = self.fanuc_frames[-1]
        frame[2] -= 1
        if frame[2] > 0:
            self.passes += 1
            if self.passes > self.max_loop_passes:
                raise GCodeError(b.line, f"more than {self.max_loop_passes} loop passes: M98 L repeats too often (or "
                                 "raise max_loop_passes)", "M99")
            return frame[1] + 1
        self.fanuc_frames.pop()
        return frame[0]

    def _loop_pass(self, b: Block) -> None:
        self.passes += 1
        if self.passes > self.max_loop_passes:
            raise GCodeError(b.line, f"more than {self.max_loop_passes} loop passes: the loop does not end (or raise "
                             "max_loop_passes)", f"o{b.oword[0]}")

    def _control(self, pc: int, b: Block) -> int | None:
        """The next block index after an O-word line (None: the program ends)."""
        name, kw, args = b.oword
        if kw == "program":
            sub = self.fanuc_subs.get(int(name))
            if sub is not None and sub[0] == pc:  # a subroutine's body: run by M98 only
                return sub[1] + 1
            self._skip(b.line, f"O{name}", "a program number (Fanuc/Haas header), no motion")
            return pc + 1
        ev = [evaluate(a, self, b.line, f"o{name}") for a in args]
        if kw == "sub":
            return self.match[pc] + 1
        if kw in ("endsub", "return"):
            if not self.frames:
                raise GCodeError(b.line, f"o{name} {kw} outside a call", f"o{name}")
            if ev:
                self.globals["_value"], self.globals["_value_returned"] = ev[0], 1.0
            frame = self.frames.pop()
            if frame.autorestore is not None:  # M73: the caller's modal state comes back
                self._restore_modal(frame.autorestore, b.line)
            for k in range(1, 31):
                self.numbered.pop(k, None)
            self.numbered.update(frame.numbered)
            return frame.return_pc
        if kw == "call":
            if isinstance(name, tuple):
                v = evaluate(name[1], self, b.line, "o[")
                if v != int(v) or v < 0:
                    raise GCodeError(b.line, f"o[...] call: the computed number {v:g} is no O-word number", "o[")
                name = str(int(v))
            if name not in self.subs:
                raise GCodeError(b.line, f"o{name} call: this file defines no o{name} sub (subroutine files are not "
                                 "searched; paste the subroutine into the program)", f"o{name}")
            if len(self.frames) >= MAX_CALL_DEPTH:
                raise GCodeError(b.line, f"o{name} call nests deeper than {MAX_CALL_DEPTH} calls", f"o{name}")
            saved = {k: self.numbered[k] for k in range(1, 31) if k in self.numbered}
            self.frames.append(_Frame(pc + 1, saved, name))
            for k in range(1, 31):
                self.numbered.pop(k, None)
            for k, v in enumerate(ev, start=1):
                self.numbered[k] = v
            self.globals["_value_returned"] = 0.0
            return self.subs[name][0] + 1
        if kw == "if":
            if ev[0] != 0:
                return pc + 1
            for j in self.chain[pc]:
                jb = self.blocks[j]
                jkw = jb.oword[1]
                if jkw == "elseif":
                    if evaluate(jb.oword[2][0], self, jb.line, f"o{name}") != 0:
                        return j + 1
                else:  # else / endif
                    return j + 1
        if kw in ("elseif", "else"):  # the taken branch ended
            return self.match[self.match[pc]] + 1
        if kw == "endif":
            return pc + 1
        if kw == "while" and pc in self.tail:  # do ... while
            if ev[0] != 0:
                self._loop_pass(b)
                return self.match[pc] + 1
            return pc + 1
        if kw == "while":
            return pc + 1 if ev[0] != 0 else self.match[pc] + 1
        if kw == "endwhile":
            self._loop_pass(b)
            return self.match[pc]
        if kw == "do":
            return pc + 1
        if kw == "repeat":
            n = ev[0]
            if n != int(n):
                raise GCodeError(b.line, f"o{name} repeat [{n:g}]: the count must be an integer", f"o{name}")
            if n <= 0:
                return self.match[pc] + 1
            self.repeat_left[(len(self.frames), pc)] = int(n)
            return pc + 1
        if kw == "endrepeat":
            key = (len(self.frames), self.match[pc])
            self.repeat_left[key] -= 1
            if self.repeat_left[key] > 0:
                self._loop_pass(b)
                return self.match[pc] + 1
            del self.repeat_left[key]
            return pc + 1
        if kw in ("break", "continue"):
            head = self.loop_of[pc]
            hkw = self.blocks[head].oword[1]
            end = self.match[head]
            if kw == "break":
                self.repeat_left.pop((len(self.frames), head), None)
                return end + 1
            if hkw == "while":
                self._loop_pass(b)
                return head
            return end  # do: evaluate the tail; repeat: count the pass at endrepeat
        raise AssertionError(kw)

//! `<enums>`, `<feature>` and `<extension>`: enum values (extension values computed from
//! offset, extnumber and dir), the requirements of core versions and extensions with their `depends`
//! conditions, and the values and aliases resolved once everything is read.

use super::parse::*;
use super::*;
use quick_xml::events::BytesStart;

impl<'a> Parser<'a> {
    pub(super) fn enums(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut g = EnumGroup {
            name: String::new(),
            kind: EnumKind::Constants,
            bitwidth: None,
            values: Vec::new(),
        };
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => g.name = v.into_owned(),
                "type" => {
                    g.kind = match &*v {
                        "enum" => EnumKind::Enum,
                        "bitmask" => EnumKind::Bitmask,
                        "constants" => EnumKind::Constants,
                        other => {
                            return Err(self.err_at(pos, format!("unknown enums type `{other}`")))
                        }
                    }
                }
                "bitwidth" => g.bitwidth = v.parse().ok(),
                _ => {}
            }
        }
        if g.name.is_empty() {
            return Err(self.err_at(pos, "<enums> without a name"));
        }
        let gi = self.reg.enum_groups.len();
        if !empty {
            loop {
                match self.child("enums")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"enum" => {
                            let vpos = self.start_pos();
                            let (v, _, _, api) = self.enum_attrs(&c, None)?;
                            self.skip(&c, cempty)?;
                            if !is_vulkan_api(api.as_deref()) {
                                continue;
                            }
                            let Some(v) = v else {
                                return Err(
                                    self.err_at(vpos, "<enum> without value, bitpos or alias")
                                );
                            };
                            if !self.values.contains_key(&v.name) {
                                self.values.insert(v.name.clone(), (gi, g.values.len()));
                                g.values.push(v);
                            }
                        }
                        b"unused" | b"comment" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "enums")),
                    },
                }
            }
        }
        self.groups.insert(g.name.clone(), gi);
        self.reg.enum_groups.push(g);
        Ok(())
    }

    /// Read an `<enum>`'s attributes. `ext_number` is the enclosing extension's number.
    /// Returns the value (None if it has neither value, bitpos, offset nor alias), the
    /// `extends` target, whether it used an offset, and its api attribute.
    #[allow(clippy::type_complexity)]
    pub(super) fn enum_attrs(
        &self,
        e: &BytesStart<'a>,
        ext_number: Option<u32>,
    ) -> Result<(Option<EnumValue>, Option<String>, bool, Option<String>), RegistryError> {
        let pos = self.start_pos();
        let mut v = EnumValue {
            name: String::new(),
            value: None,
            bitpos: None,
            alias: None,
            raw: None,
            c_type: None,
            added_by: None,
            protect: None,
            deprecated: None,
        };
        let (mut extends, mut offset, mut extnumber, mut neg, mut api, mut has) =
            (None, None, None, false, None, false);
        for (k, val) in self.attrs(e)? {
            match k {
                "name" => v.name = val.into_owned(),
                "value" => {
                    has = true;
                    match parse_int_literal(&val) {
                        Some(x) if !val.contains('.') && !val.contains('"') => {
                            v.value = Some(x);
                            if val.contains('~') || val.contains('U') || val.contains('(') {
                                v.raw = Some(val.into_owned());
                            }
                        }
                        _ => v.raw = Some(val.into_owned()),
                    }
                }
                "bitpos" => {
                    has = true;
                    let b: u32 = val
                        .parse()
                        .map_err(|_| self.err_at(pos, format!("bad bitpos `{val}`")))?;
                    if b > 63 {
                        return Err(self.err_at(pos, format!("bitpos {b} out of range")));
                    }
                    v.bitpos = Some(b);
                    v.value = Some(1i64 << b);
                }
                "alias" => {
                    has = true;
                    v.alias = Some(val.into_owned())
                }
                "offset" => {
                    has = true;
                    offset = Some(
                        val.parse::<i64>()
                            .map_err(|_| self.err_at(pos, format!("bad offset `{val}`")))?,
                    )
                }
                "extnumber" => {
                    extnumber = Some(
                        val.parse::<i64>()
                            .map_err(|_| self.err_at(pos, format!("bad extnumber `{val}`")))?,
                    )
                }
                "dir" => neg = val == "-",
                "extends" => extends = Some(val.into_owned()),
                "type" => v.c_type = Some(val.into_owned()),
                "api" => api = Some(val.into_owned()),
                "protect" => v.protect = Some(val.into_owned()),
                "deprecated" => v.deprecated = Some(val.into_owned()),
                _ => {}
            }
        }
        if v.name.is_empty() {
            return Err(self.err_at(pos, "<enum> without a name"));
        }
        if let Some(off) = offset {
            let n = match extnumber.or(ext_number.map(i64::from)) {
                Some(n) => n,
                None => {
                    return Err(self.err_at(pos, format!("{}: offset without extnumber", v.name)))
                }
            };
            // the extension enum scheme: 1000000000 + (extnumber - 1) * 1000 + offset, negated by dir="-"
            let x = n
                .checked_sub(1)
                .and_then(|b| b.checked_mul(1000))
                .and_then(|b| b.checked_add(1_000_000_000))
                .and_then(|b| b.checked_add(off))
                .and_then(|x| if neg { x.checked_neg() } else { Some(x) })
                .ok_or_else(|| {
                    self.err_at(
                        pos,
                        format!(
                            "{}: extnumber {n} and offset {off} give a value out of range",
                            v.name
                        ),
                    )
                })?;
            v.value = Some(x);
        } else if neg {
            if let Some(x) = v.value {
                v.value = Some(x.checked_neg().ok_or_else(|| {
                    self.err_at(pos, format!("{}: value {x} cannot be negated", v.name))
                })?);
            }
        }
        Ok((has.then_some(v), extends, offset.is_some(), api))
    }

    pub(super) fn feature(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut f = Feature {
            name: String::new(),
            number: String::new(),
            api: Vec::new(),
            depends: None,
            require: Vec::new(),
            remove: Vec::new(),
        };
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => f.name = v.into_owned(),
                "number" => f.number = v.into_owned(),
                "api" => f.api = split_list(&v),
                "depends" => f.depends = Some(self.condition(&v, pos)?),
                _ => {}
            }
        }
        if f.name.is_empty() {
            return Err(self.err_at(pos, "<feature> without a name"));
        }
        let keep = f.api.is_empty() || f.api.iter().any(|a| a == "vulkan");
        let name = f.name.clone();
        if !empty {
            loop {
                match self.child("feature")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"require" => {
                            if let Some(r) = self.require(&c, cempty, &name, None, keep)? {
                                f.require.push(r);
                            }
                        }
                        b"remove" => {
                            if let Some(r) = self.require(&c, cempty, &name, None, false)? {
                                f.remove.push(r);
                            }
                        }
                        b"comment" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "feature")),
                    },
                }
            }
        }
        if keep {
            self.reg.features.push(f);
        }
        Ok(())
    }

    pub(super) fn condition(&self, s: &str, pos: usize) -> Result<Condition, RegistryError> {
        Condition::parse(s).map_err(|(off, msg)| {
            self.err_at(
                pos,
                format!(
                    "bad depends `{}` (at {off}): {msg}",
                    crate::error::excerpt(s)
                ),
            )
        })
    }

    /// A `<require>`/`<remove>` block. Enum values it adds are queued when `apply` is set.
    /// Returns None if the block is for another API.
    pub(super) fn require(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
        owner: &str,
        ext_number: Option<u32>,
        apply: bool,
    ) -> Result<Option<Require>, RegistryError> {
        let pos = self.start_pos();
        let mut r = Require::default();
        let mut old_deps = Vec::new();
        for (k, v) in self.attrs(e)? {
            match k {
                "depends" => r.depends = Some(self.condition(&v, pos)?),
                "api" => r.api = Some(v.into_owned()),
                "comment" => r.comment = Some(v.into_owned()),
                "extension" | "feature" => old_deps.push(v.into_owned()),
                _ => {}
            }
        }
        if r.depends.is_none() && !old_deps.is_empty() {
            let joined = old_deps.join("+");
            r.depends = Some(self.condition(&joined, pos)?);
        }
        let keep = is_vulkan_api(r.api.as_deref());
        if !empty {
            loop {
                match self.child("require")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => {
                        let cpos = self.start_pos();
                        match c.name().as_ref() {
                            b"type" | b"command" => {
                                let name = self
                                    .attrs(&c)?
                                    .into_iter()
                                    .find(|(k, _)| *k == "name")
                                    .map(|(_, v)| v.into_owned());
                                let is_type = c.name().as_ref() == b"type";
                                self.skip(&c, cempty)?;
                                let Some(name) = name else {
                                    return Err(self.err_at(cpos, "reference without a name"));
                                };
                                if is_type {
                                    r.types.push(name);
                                } else {
                                    r.commands.push(name);
                                }
                            }
                            b"enum" => {
                                let (v, extends, _, api) = self.enum_attrs(&c, ext_number)?;
                                self.skip(&c, cempty)?;
                                if !is_vulkan_api(api.as_deref()) {
                                    continue;
                                }
                                let name = match &v {
                                    Some(v) => v.name.clone(),
                                    None => self
                                        .attrs(&c)
                                        .ok()
                                        .and_then(|a| {
                                            a.into_iter()
                                                .find(|(k, _)| *k == "name")
                                                .map(|(_, v)| v.into_owned())
                                        })
                                        .unwrap_or_default(),
                                };
                                r.enums.push(name);
                                if let (true, true, Some(mut v)) = (apply, keep, v) {
                                    v.added_by = Some(owner.to_string());
                                    let target = extends.unwrap_or_default();
                                    self.pending_ext.push((
                                        target,
                                        PendingValue {
                                            value: v,
                                            offset_pos: cpos,
                                        },
                                    ));
                                }
                            }
                            b"feature" => {
                                let a = self.attrs(&c)?;
                                self.skip(&c, cempty)?;
                                let get = |k: &str| {
                                    a.iter()
                                        .find(|(kk, _)| *kk == k)
                                        .map(|(_, v)| v.to_string())
                                        .unwrap_or_default()
                                };
                                r.features.push(FeatureRef {
                                    name: get("name"),
                                    structure: get("struct"),
                                });
                            }
                            b"comment" => self.skip(&c, cempty)?,
                            _ => return Err(self.unexpected(&c, "require")),
                        }
                    }
                }
            }
        }
        Ok(keep.then_some(r))
    }

    pub(super) fn extension(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
    ) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut x = Extension {
            name: String::new(),
            number: 0,
            ext_type: None,
            supported: Vec::new(),
            depends: None,
            promotedto: None,
            deprecatedby: None,
            obsoletedby: None,
            platform: None,
            provisional: false,
            specialuse: Vec::new(),
            ratified: Vec::new(),
            author: None,
            contact: None,
            require: Vec::new(),
            remove: Vec::new(),
        };
        let mut requires = None;
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => x.name = v.into_owned(),
                "number" => {
                    x.number = v
                        .parse()
                        .map_err(|_| self.err_at(pos, format!("bad extension number `{v}`")))?
                }
                "type" => x.ext_type = Some(v.into_owned()),
                "supported" => x.supported = split_list(&v),
                "depends" => x.depends = Some(self.condition(&v, pos)?),
                "requires" => requires = Some(v.into_owned()),
                "promotedto" => x.promotedto = Some(v.into_owned()),
                "deprecatedby" => x.deprecatedby = Some(v.into_owned()),
                "obsoletedby" => x.obsoletedby = Some(v.into_owned()),
                "platform" => x.platform = Some(v.into_owned()),
                "provisional" => x.provisional = v == "true",
                "specialuse" => x.specialuse = split_list(&v),
                "ratified" => x.ratified = split_list(&v),
                "author" => x.author = Some(v.into_owned()),
                "contact" => x.contact = Some(v.into_owned()),
                _ => {}
            }
        }
        if x.name.is_empty() {
            return Err(self.err_at(pos, "<extension> without a name"));
        }
        if x.depends.is_none() {
            if let Some(req) = requires {
                // old registries: a comma-separated list of required extensions (all needed)
                x.depends = Some(self.condition(&req.replace(',', "+"), pos)?);
            }
        }
        let apply = x.is_vulkan();
        let name = x.name.clone();
        if !empty {
            loop {
                match self.child("extension")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"require" => {
                            if let Some(r) =
                                self.require(&c, cempty, &name, Some(x.number), apply)?
                            {
                                x.require.push(r);
                            }
                        }
                        b"remove" => {
                            if let Some(r) =
                                self.require(&c, cempty, &name, Some(x.number), false)?
                            {
                                x.remove.push(r);
                            }
                        }
                        b"comment" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "extension")),
                    },
                }
            }
        }
        self.reg.extensions.push(x);
        Ok(())
    }

    pub(super) fn apply_pending(&mut self) -> Result<(), RegistryError> {
        for (target, pv) in std::mem::take(&mut self.pending_ext) {
            if self.values.contains_key(&pv.value.name) {
                continue;
            }
            if target.is_empty() {
                let idx = self.reg.ext_constants.len();
                self.values.insert(pv.value.name.clone(), (usize::MAX, idx));
                self.reg.ext_constants.push(pv.value);
                continue;
            }
            let Some(&gi) = self.groups.get(&target) else {
                return Err(self.err_at(
                    pv.offset_pos,
                    format!("{} extends unknown enum {}", pv.value.name, target),
                ));
            };
            let g = &mut self.reg.enum_groups[gi];
            self.values
                .insert(pv.value.name.clone(), (gi, g.values.len()));
            g.values.push(pv.value);
        }
        Ok(())
    }

    pub(super) fn resolve_aliases(&mut self) {
        let lookup = |reg: &Registry,
                      values: &FastMap<String, (usize, usize)>,
                      name: &str|
         -> Option<(usize, usize)> {
            let _ = reg;
            values.get(name).copied()
        };
        let mut fixes = Vec::new();
        fn get(reg: &Registry, (g, v): (usize, usize)) -> &EnumValue {
            if g == usize::MAX {
                &reg.ext_constants[v]
            } else {
                &reg.enum_groups[g].values[v]
            }
        }
        for (name, &loc) in &self.values {
            let ev = get(&self.reg, loc);
            if ev.value.is_some() || ev.alias.is_none() {
                continue;
            }
            let mut cur = ev.alias.clone();
            let mut found = None;
            for _ in 0..8 {
                let Some(a) = cur else { break };
                let Some(l) = lookup(&self.reg, &self.values, &a) else {
                    break;
                };
                let t = get(&self.reg, l);
                if t.value.is_some() || t.raw.is_some() {
                    found = Some((t.value, t.raw.clone(), t.bitpos));
                    break;
                }
                cur = t.alias.clone();
            }
            if let Some(f) = found {
                fixes.push((name.clone(), loc, f));
            }
        }
        for (_, (g, v), (value, raw, bitpos)) in fixes {
            let ev = if g == usize::MAX {
                &mut self.reg.ext_constants[v]
            } else {
                &mut self.reg.enum_groups[g].values[v]
            };
            ev.value = value;
            if ev.raw.is_none() {
                ev.raw = raw;
            }
            if ev.bitpos.is_none() {
                ev.bitpos = bitpos;
            }
        }
    }
}

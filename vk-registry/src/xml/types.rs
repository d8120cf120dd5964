//! `<types>` and `<commands>`: type definitions with their members, and commands with their
//! parameters, each as a C declaration collapsed and parsed for pointers, arrays and bit fields.

use super::parse::*;
use super::*;
use quick_xml::events::BytesStart;

impl<'a> Parser<'a> {
    pub(super) fn type_def(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
    ) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut t = TypeDef {
            name: String::new(),
            category: TypeCategory::External,
            alias: None,
            api: None,
            parent: Vec::new(),
            dispatchable: None,
            objtypeenum: None,
            base: None,
            requires: None,
            bitvalues: None,
            structextends: Vec::new(),
            returnedonly: false,
            allowduplicate: false,
            deprecated: None,
            members: Vec::new(),
        };
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => t.name = v.into_owned(),
                "category" => {
                    t.category = match &*v {
                        "struct" => TypeCategory::Struct,
                        "union" => TypeCategory::Union,
                        "handle" => TypeCategory::Handle,
                        "enum" => TypeCategory::Enum,
                        "bitmask" => TypeCategory::Bitmask,
                        "basetype" => TypeCategory::BaseType,
                        "define" => TypeCategory::Define,
                        "include" => TypeCategory::Include,
                        "funcpointer" => TypeCategory::FuncPointer,
                        other => {
                            return Err(self.err_at(pos, format!("unknown type category `{other}`")))
                        }
                    }
                }
                "alias" => t.alias = Some(v.into_owned()),
                "api" => t.api = Some(v.into_owned()),
                "parent" => t.parent = split_list(&v),
                "objtypeenum" => t.objtypeenum = Some(v.into_owned()),
                "requires" => t.requires = Some(v.into_owned()),
                "bitvalues" => t.bitvalues = Some(v.into_owned()),
                "structextends" => t.structextends = split_list(&v),
                "returnedonly" => t.returnedonly = v == "true",
                "allowduplicate" => t.allowduplicate = v == "true",
                "deprecated" => t.deprecated = Some(v.into_owned()),
                _ => {}
            }
        }
        if !empty {
            loop {
                match self.child("type")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"member" => {
                            let m = self.member(&c, cempty, "member")?;
                            if is_vulkan_api(m.api.as_deref()) {
                                t.members.push(m);
                            }
                        }
                        b"name" => {
                            let s = self.text_of(&c, cempty, "name")?;
                            if t.name.is_empty() {
                                t.name = s;
                            }
                        }
                        b"type" => {
                            let s = self.text_of(&c, cempty, "type")?;
                            if t.base.is_none() {
                                t.base = Some(s);
                            }
                        }
                        b"comment" => self.skip(&c, cempty)?,
                        b"apientry" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "type")),
                    },
                }
            }
        }
        if t.name.is_empty() {
            return Err(self.err_at(pos, "<type> without a name"));
        }
        if t.category == TypeCategory::Handle && t.alias.is_none() {
            t.dispatchable = match t.base.as_deref() {
                Some("VK_DEFINE_HANDLE") => Some(true),
                Some("VK_DEFINE_NON_DISPATCHABLE_HANDLE") => Some(false),
                _ => None,
            };
        }
        if t.category == TypeCategory::Bitmask && t.bitvalues.is_none() {
            // old registries name the FlagBits enum with `requires`
            if let Some(r) = &t.requires {
                t.bitvalues = Some(r.clone());
            }
        }
        if is_vulkan_api(t.api.as_deref()) {
            self.reg.types.push(t);
        }
        Ok(())
    }

    /// The text content of a simple element such as `<name>`.
    pub(super) fn text_of(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
        ctx: &str,
    ) -> Result<String, RegistryError> {
        let _ = e;
        let mut s = String::new();
        if empty {
            return Ok(s);
        }
        loop {
            match self.child(ctx)? {
                Ev::Close => return Ok(s),
                Ev::Text(t) => s.push_str(&self.unescape(&t)?),
                Ev::Open(c, _) => return Err(self.unexpected(&c, ctx)),
            }
        }
    }

    /// A `<member>`, `<param>` or `<proto>`.
    pub(super) fn member(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
        ctx: &'static str,
    ) -> Result<Member, RegistryError> {
        let pos = self.start_pos();
        let mut m = Member::default();
        for (k, v) in self.attrs(e)? {
            match k {
                "optional" => m.optional = v.split(',').map(|x| x.trim() == "true").collect(),
                "len" => m.len = Some(v.into_owned()),
                "altlen" => m.altlen = Some(v.into_owned()),
                "values" => m.values = Some(v.into_owned()),
                "noautovalidity" => m.noautovalidity = v == "true",
                "limittype" => m.limittype = Some(v.into_owned()),
                "selector" => m.selector = Some(v.into_owned()),
                "selection" => m.selection = Some(v.into_owned()),
                "externsync" => m.externsync = Some(v.into_owned()),
                "objecttype" => m.objecttype = Some(v.into_owned()),
                "stride" => m.stride = Some(v.into_owned()),
                "validstructs" => m.validstructs = split_list(&v),
                "api" => m.api = Some(v.into_owned()),
                "deprecated" => m.deprecated = Some(v.into_owned()),
                _ => {}
            }
        }
        if empty {
            return Err(self.err_at(pos, format!("empty <{ctx}>")));
        }
        let mut decl = String::new();
        let mut after_name = String::new();
        let mut stage = 0u8; // 0 before <type>, 1 after type, 2 after name
        let mut between = String::new();
        loop {
            match self.child(ctx)? {
                Ev::Close => break,
                Ev::Text(t) => {
                    let t = self.unescape(&t)?;
                    decl.push_str(&t);
                    match stage {
                        1 => between.push_str(&t),
                        2 => after_name.push_str(&t),
                        _ => {}
                    }
                }
                Ev::Open(c, cempty) => match c.name().as_ref() {
                    b"type" => {
                        let s = self.text_of(&c, cempty, "type")?;
                        decl.push_str(&s);
                        m.type_name = s;
                        stage = 1;
                    }
                    b"name" => {
                        let s = self.text_of(&c, cempty, "name")?;
                        decl.push_str(&s);
                        m.name = s;
                        stage = 2;
                    }
                    b"enum" => {
                        let s = self.text_of(&c, cempty, "enum")?;
                        decl.push_str(&s);
                        if stage == 2 {
                            after_name.push_str(&s);
                        }
                    }
                    b"comment" => self.skip(&c, cempty)?,
                    _ => return Err(self.unexpected(&c, ctx)),
                },
            }
        }
        if m.name.is_empty() {
            return Err(self.err_at(pos, format!("<{ctx}> without a <name>")));
        }
        m.decl = collapse(&decl);
        m.is_const = m.decl.starts_with("const ");
        m.pointer_depth = between.bytes().filter(|&b| b == b'*').count() as u8;
        // arrays and bit-fields after the name
        let rest = after_name.trim();
        if let Some(bits) = rest.strip_prefix(':') {
            m.bitfield = bits.trim().parse().ok();
        } else {
            let mut r = rest;
            while let Some(open) = r.find('[') {
                let Some(close) = r[open..].find(']') else {
                    return Err(self.err_at(pos, format!("unclosed `[` in <{ctx}> {}", m.name)));
                };
                m.array.push(r[open + 1..open + close].trim().to_string());
                r = &r[open + close + 1..];
            }
        }
        Ok(m)
    }

    pub(super) fn command(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut c = Command::default();
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => c.name = v.into_owned(),
                "alias" => c.alias = Some(v.into_owned()),
                "api" => c.api = Some(v.into_owned()),
                "successcodes" => c.successcodes = split_list(&v),
                "errorcodes" => c.errorcodes = split_list(&v),
                "queues" => c.queues = split_list(&v),
                "renderpass" => c.renderpass = Some(v.into_owned()),
                "videocoding" => c.videocoding = Some(v.into_owned()),
                "cmdbufferlevel" => c.cmdbufferlevel = split_list(&v),
                "tasks" => c.tasks = split_list(&v),
                _ => {}
            }
        }
        if !empty {
            loop {
                match self.child("command")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(ch, cempty) => match ch.name().as_ref() {
                        b"proto" => {
                            let p = self.member(&ch, cempty, "proto")?;
                            c.name = p.name;
                            c.return_type = p.type_name;
                        }
                        b"param" => {
                            let p = self.member(&ch, cempty, "param")?;
                            if is_vulkan_api(p.api.as_deref()) {
                                c.params.push(p);
                            }
                        }
                        b"implicitexternsyncparams" => {
                            if !cempty {
                                loop {
                                    match self.child("implicitexternsyncparams")? {
                                        Ev::Close => break,
                                        Ev::Text(_) => {}
                                        Ev::Open(p, pempty) if p.name().as_ref() == b"param" => {
                                            let s = self.text_of(&p, pempty, "param")?;
                                            c.implicit_externsync.push(collapse(&s));
                                        }
                                        Ev::Open(p, _) => {
                                            return Err(
                                                self.unexpected(&p, "implicitexternsyncparams")
                                            )
                                        }
                                    }
                                }
                            }
                        }
                        b"description" | b"comment" => self.skip(&ch, cempty)?,
                        _ => return Err(self.unexpected(&ch, "command")),
                    },
                }
            }
        }
        if c.name.is_empty() {
            return Err(self.err_at(pos, "<command> without a name"));
        }
        if is_vulkan_api(c.api.as_deref()) {
            self.reg.commands.push(c);
        }
        Ok(())
    }
}
